#pragma once
// HTTP routes of map persistence: GET /api/map/snapshot (download the newest snapshot file),
// POST /api/map/snapshot (write one now), POST /api/map/load (load a snapshot file's clients
// into the running server; needs --http-token). The handlers talk to a MapStore, which does the
// work on its own thread: they never take SLAM locks.
#include <cstdint>
#include <optional>
#include <string>

namespace httplib {
class Server;
}

namespace cslam::http {

class MapStore {
 public:
  virtual ~MapStore() = default;
  // Path of the newest good snapshot file, if any.
  virtual std::optional<std::string> snapshot_file() const = 0;
  // Asks for a snapshot now and waits up to timeout_s. Returns an empty string on success, else
  // the one-line error (or "still running" on timeout).
  virtual std::string write_now(double timeout_s) = 0;
  // Loads the clients of the snapshot file `name` (inside the store's import folder) into the
  // running system; returns the number of clients loaded. Throws InputError on a bad file/name.
  virtual std::size_t load(const std::string& name) = 0;
  // JSON object with counters and timings of snapshot writes.
  virtual std::string stats_json() const = 0;
};

// Registers the routes; `token` is the server's --http-token (POST /api/map/load refuses without one).
void add_map_routes(httplib::Server& server, MapStore& store, const std::string& token);

}  // namespace cslam::http
