#pragma once
// The HTTP guard's request parser (server/http/http_guard.*): finds one complete request in a
// connection's buffer and normalises it for httplib (chunked body decoded, Content-Length set,
// Expect removed), or says which limit it broke. Pure functions over a byte buffer.
#include <cstddef>
#include <string>

#include "server/http/http_guard.h"

namespace cslam::http {

enum class Parse { kIncomplete, kComplete, kHeaderTooLarge, kBodyTooLarge, kBad };

struct Parsed {
  std::string request;  // normalised: request line, headers, Content-Length, body
  std::size_t consumed = 0;
  bool close = false;  // the client asked for Connection: close (or HTTP/1.0 without keep-alive)
  bool expect_continue = false;
};

// Looks for one request at the start of `buf` within cfg's header and body limits.
Parse parse_request(const std::string& buf, const GuardConfig& cfg, Parsed* out);

// Lower-case ASCII copy (header names and values).
std::string lower(std::string s);

}  // namespace cslam::http
