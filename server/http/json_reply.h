#pragma once
// Small helpers for JSON replies of the HTTP layer.
#include <string>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace cslam::http {

inline void json_reply(httplib::Response& res, const nlohmann::json& body, int status = 200) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(), "application/json");
}

inline void json_error(httplib::Response& res, int status, const std::string& message) {
  json_reply(res, {{"error", message}, {"status", status}}, status);
}

}  // namespace cslam::http
