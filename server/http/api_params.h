#pragma once
// Request helpers of the JSON API routes (server/http/api_routes.*): strictly parsed query
// parameters, and `guarded`, the wrapper that checks a request's input and turns exceptions into
// JSON errors.
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>

#include "core/error.h"
// After every Eigen include: <resolv.h> (pulled in by httplib.h) defines a macro _res.
#include "server/http/json_reply.h"

namespace cslam::http {

// A strictly parsed integer parameter: nullopt if absent; throws std::invalid_argument if malformed.
inline std::optional<long> int_param(const httplib::Request& req, const std::string& name, long lo, long hi) {
  if (!req.has_param(name.c_str())) return std::nullopt;
  const std::string v = req.get_param_value(name.c_str());
  std::size_t used = 0;
  long x = 0;
  try {
    x = std::stol(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (v.empty() || used != v.size() || x < lo || x > hi)
    throw std::invalid_argument("parameter " + name + " must be an integer in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "], got '" + v + "'");
  return x;
}

inline std::optional<double> double_param(const httplib::Request& req, const std::string& name, double lo, double hi) {
  if (!req.has_param(name.c_str())) return std::nullopt;
  const std::string v = req.get_param_value(name.c_str());
  std::size_t used = 0;
  double x = 0;
  try {
    x = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (v.empty() || used != v.size() || !(x >= lo && x <= hi))
    throw std::invalid_argument("parameter " + name + " must be a number in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "], got '" + v + "'");
  return x;
}

inline std::string param_or(const httplib::Request& req, const char* name, const std::string& fallback) {
  return req.has_param(name) ? req.get_param_value(name) : fallback;
}

// Runs a handler body. Input is checked first (a request part that is not clean UTF-8 text is
// a 400 with a sanitised echo, before any handler can echo it); std::invalid_argument and
// ConfigError become a 400 with their message, anything else a 500. The error path cannot throw
// (json_error sanitises and catches).
template <typename F>
httplib::Server::Handler guarded(F f) {
  return [f](const httplib::Request& req, httplib::Response& res) {
    if (const auto bad = unclean_request_part(req)) return json_error(res, 400, *bad);
    for (std::size_t i = 1; i < req.matches.size(); ++i)
      if (!is_clean_text(req.matches[i].str()))
        return json_error(res, 400, "id is not valid UTF-8 text: '" + sanitized(req.matches[i].str()) + "'");
    try {
      f(req, res);
    } catch (const std::invalid_argument& e) {
      json_error(res, 400, e.what());
    } catch (const ConfigError& e) {
      json_error(res, 400, e.what());
    } catch (const std::exception& e) {
      json_error(res, 500, std::string("internal error: ") + e.what());
    } catch (...) {
      json_error(res, 500, "internal error");
    }
  };
}

}  // namespace cslam::http
