#include "server/session_table.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace cslam::server {

const char* to_string(SessionState state) {
  switch (state) {
    case SessionState::kActive:
      return "active";
    case SessionState::kDisconnected:
      return "disconnected";
    case SessionState::kDone:
      return "done";
  }
  return "unknown";
}

const char* to_string(Admission admission) {
  switch (admission) {
    case Admission::kNew:
      return "new";
    case Admission::kResume:
      return "resume";
    case Admission::kBusy:
      return "busy";
    case Admission::kWrongKey:
      return "wrong_key";
    case Admission::kFull:
      return "full";
  }
  return "unknown";
}

namespace {
std::string seconds(double s) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g s", s);
  return buf;
}
}  // namespace

double StampHistory::median_interval() const {
  if (count_ == 0) return 0;
  std::array<double, kIntervals> v = intervals_;
  auto mid = v.begin() + std::ptrdiff_t(count_ / 2);
  std::nth_element(v.begin(), mid, v.begin() + std::ptrdiff_t(count_));
  return *mid;
}

double StampHistory::allowed_jump(Clock::time_point now, const TimestampBound& bound) const {
  const double wall = has_last_ ? std::max(0.0, std::chrono::duration<double>(now - last_wall_).count()) : 0.0;
  return std::max(bound.min_jump_s, bound.interval_factor * median_interval()) + bound.wall_factor * wall;
}

StampHistory::Verdict StampHistory::check(double t, Clock::time_point now, const TimestampBound& bound) {
  if (bound.min_jump_s <= 0 || !has_last_ || t <= last_) return {};  // backwards: the SLAM front end answers it
  const double jump = t - last_, allowed = allowed_jump(now, bound);
  if (jump <= allowed) {
    pending_ = 0;
    return {};
  }
  // Out of bound. Agrees with the previous out-of-bound frame (a genuine jump of the time base)?
  const double step = std::max(bound.min_jump_s, bound.interval_factor * median_interval());
  pending_ = pending_ > 0 && t > pending_last_ && t - pending_last_ <= step ? pending_ + 1 : 1;
  pending_last_ = t;
  if (pending_ >= std::max(1, bound.confirm_frames) && bound.confirm_frames > 0) {
    pending_ = 0;
    epoch_ = true;
    return {true, true,
            "timestamps jumped " + seconds(jump) + " ahead over " + std::to_string(bound.confirm_frames) +
                " consecutive frames: taken as a new time base"};
  }
  return {false, false,
          "timestamp " + seconds(t) + " is " + seconds(jump) + " past the last accepted frame's (" + seconds(last_) +
              "); at most " + seconds(allowed) + " is allowed (median frame interval " + seconds(median_interval()) +
              ")"};
}

void StampHistory::accept(double t, Clock::time_point now) {
  if (has_last_ && t <= last_) return;  // refused downstream (not increasing): changes nothing
  if (has_last_ && !epoch_) {
    intervals_[next_] = t - last_;
    next_ = (next_ + 1) % kIntervals;
    count_ = std::min(count_ + 1, kIntervals);
  }
  if (epoch_) count_ = next_ = 0;
  epoch_ = false;
  pending_ = 0;
  has_last_ = true;
  last_ = t;
  last_wall_ = now;
}

Admission SessionTable::admit(ClientId id, const std::string& routing_id, const std::string& key) const {
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return sessions_.size() >= max_clients_ ? Admission::kFull : Admission::kNew;
  const Session& s = it->second;
  if (!s.key.empty() || !key.empty()) {
    // CURVE: the key that owns the session may always take it over (its old connection is dead
    // or superseded); a restored session without a recorded key goes to any key bound to the id.
    if (s.key.empty() && s.restored) return Admission::kResume;
    return s.key == key ? Admission::kResume : Admission::kWrongKey;
  }
  if (s.routing_id == routing_id) return Admission::kResume;
  return s.state == SessionState::kActive ? Admission::kBusy : Admission::kResume;
}

std::pair<Session*, bool> SessionTable::open(const ClientInfo& info, const std::string& routing_id,
                                             Clock::time_point now, const std::string& key) {
  // A routing id speaks for one client at a time.
  if (auto it = by_routing_.find(routing_id); it != by_routing_.end() && it->second != info.id) by_routing_.erase(it);
  auto [it, inserted] = sessions_.try_emplace(info.id);
  Session& s = it->second;
  bool resumed = !inserted;
  if (inserted) {
    s.info = info;
  } else {
    by_routing_.erase(s.routing_id);
    if (s.restored) {  // its first connection in this server's life
      s.restored = false;
      s.connections = 1;
    } else {
      ++s.connections;
    }
  }
  s.routing_id = routing_id;
  s.key = key;
  s.state = SessionState::kActive;
  s.last_seen = now;
  by_routing_[routing_id] = info.id;
  return {&s, resumed};
}

Session& SessionTable::restore(const RestoredSession& restored, Clock::time_point now) {
  if (sessions_.count(restored.info.id))
    throw std::invalid_argument("session " + std::to_string(restored.info.id) + " restored twice");
  if (sessions_.size() >= max_clients_)
    throw std::invalid_argument("restoring session " + std::to_string(restored.info.id) + ": more than " +
                                std::to_string(max_clients_) + " sessions (raise --max-clients)");
  Session& s = sessions_[restored.info.id];
  s.info = restored.info;
  s.last_seq = restored.last_seq;
  s.key = restored.key;
  s.state = SessionState::kDisconnected;
  s.last_seen = now;
  s.connections = 0;
  s.restored = true;
  return s;
}

void SessionTable::restore(const ClientInfo& info, std::uint64_t last_seq, Clock::time_point now) {
  restore(RestoredSession{info, last_seq, ""}, now);
}

Session* SessionTable::by_routing_id(const std::string& routing_id) {
  auto it = by_routing_.find(routing_id);
  return it == by_routing_.end() ? nullptr : by_client(it->second);
}

Session* SessionTable::by_client(ClientId id) {
  auto it = sessions_.find(id);
  return it == sessions_.end() ? nullptr : &it->second;
}

std::vector<ClientId> SessionTable::expire(Clock::time_point now, std::chrono::duration<double> timeout) {
  std::vector<ClientId> expired;
  for (auto& [id, s] : sessions_) {
    if (s.state == SessionState::kActive && now - s.last_seen > timeout) {
      s.state = SessionState::kDisconnected;
      expired.push_back(id);
    }
  }
  return expired;
}

std::vector<ClientId> SessionTable::reclaimable(Clock::time_point now, std::chrono::duration<double> ttl) const {
  std::vector<ClientId> out;
  for (const auto& [id, s] : sessions_)
    if (s.state != SessionState::kActive && s.idle() && now - s.last_seen > ttl) out.push_back(id);
  return out;
}

void SessionTable::erase(ClientId id) {
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return;
  if (it->second.state == SessionState::kDone) ++erased_done_;
  if (auto r = by_routing_.find(it->second.routing_id); r != by_routing_.end() && r->second == id) by_routing_.erase(r);
  sessions_.erase(it);
}

bool SessionTable::all_finished(std::size_t expected) const {
  std::size_t done = erased_done_;
  for (const auto& [id, s] : sessions_) {
    if (s.state == SessionState::kActive) return false;
    done += s.state == SessionState::kDone;
  }
  return done > 0 && done >= expected;
}

std::string routing_id_text(const std::string& routing_id) {
  std::string out;
  char buf[4];
  for (unsigned char c : routing_id) {
    if (c >= 0x21 && c < 0x7f) {
      out += char(c);
    } else {
      std::snprintf(buf, sizeof buf, "%02x", c);
      out += buf;
    }
  }
  return out.empty() ? "(empty)" : out;
}

}  // namespace cslam::server
