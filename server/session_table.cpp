#include "server/session_table.h"

#include <cstdio>

namespace cslam::server {

const char* to_string(SessionState state) {
  switch (state) {
    case SessionState::kActive: return "active";
    case SessionState::kDisconnected: return "disconnected";
    case SessionState::kDone: return "done";
  }
  return "unknown";
}

std::pair<Session*, bool> SessionTable::open(const ClientInfo& info, const std::string& routing_id,
                                             Clock::time_point now) {
  // A routing id speaks for one client at a time.
  if (auto it = by_routing_.find(routing_id); it != by_routing_.end() && it->second != info.id) by_routing_.erase(it);
  auto [it, inserted] = sessions_.try_emplace(info.id);
  Session& s = it->second;
  if (inserted) {
    s.info = info;
  } else {
    by_routing_.erase(s.routing_id);
    ++s.connections;
  }
  s.routing_id = routing_id;
  s.state = SessionState::kActive;
  s.last_seen = now;
  by_routing_[routing_id] = info.id;
  return {&s, !inserted};
}

void SessionTable::restore(const ClientInfo& info, std::uint64_t last_seq, Clock::time_point now) {
  Session& s = sessions_[info.id];
  s.info = info;
  s.routing_id.clear();
  s.state = SessionState::kDisconnected;
  s.last_seq = last_seq;
  s.in_flight = 0;
  s.last_seen = now;
  s.connections = 0;
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

bool SessionTable::all_finished(std::size_t expected) const {
  std::size_t done = 0;
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
