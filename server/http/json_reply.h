#pragma once
// Small helpers for JSON replies of the HTTP layer, and the checks that keep untrusted bytes out
// of them: the JSON library throws on a string that is not UTF-8, so an error reply that echoes
// a request's id or parameter must never see raw bytes (docs/security.md, "HTTP input").
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace cslam::http {

// Length of the valid UTF-8 sequence (no overlong forms, no surrogates, at most U+10FFFF) that
// starts at s[i], or 0 if none does.
inline std::size_t utf8_sequence(std::string_view s, std::size_t i) {
  const auto byte = [&s](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  std::uint32_t cp = 0;
  if ((c & 0xE0) == 0xC0)
    n = 2, cp = c & 0x1F;
  else if ((c & 0xF0) == 0xE0)
    n = 3, cp = c & 0x0F;
  else if ((c & 0xF8) == 0xF0)
    n = 4, cp = c & 0x07;
  else
    return 0;
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (byte(i + k) & 0x3F);
  }
  static constexpr std::uint32_t kMin[5] = {0, 0, 0x80, 0x800, 0x10000};
  if (cp < kMin[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

// True if `s` is valid UTF-8 without control characters (an id or a parameter a user could type).
inline bool is_clean_text(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = utf8_sequence(s, i);
    if (n == 0) return false;
    if (n == 1 && (static_cast<unsigned char>(s[i]) < 0x20 || s[i] == 0x7F)) return false;
    i += n;
  }
  return true;
}

// A printable copy of untrusted bytes for an error message: valid UTF-8 kept, control characters
// and invalid bytes as \xHH, cut at max_bytes (with "..."). Never throws but for bad_alloc.
inline std::string sanitized(std::string_view s, std::size_t max_bytes = 96) {
  std::string out;
  for (std::size_t i = 0; i < s.size();) {
    if (out.size() >= max_bytes) return out + "...";
    const std::size_t n = utf8_sequence(s, i);
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (n == 0 || (n == 1 && (c < 0x20 || c == 0x7F))) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
  return out;
}

// The first part of a request (decoded path, a parameter's name or value) that is not clean
// text, described for a 400 with a sanitised echo; nullopt if all are clean.
inline std::optional<std::string> unclean_request_part(const httplib::Request& req) {
  if (!is_clean_text(req.path))
    return "the path is not valid UTF-8 text (or holds control characters): '" + sanitized(req.path) + "'";
  for (const auto& [name, value] : req.params) {
    if (!is_clean_text(name))
      return "a parameter name is not valid UTF-8 text (or holds control characters): '" + sanitized(name) + "'";
    if (!is_clean_text(value))
      return "parameter " + name + " is not valid UTF-8 text (or holds control characters): '" + sanitized(value) + "'";
  }
  return std::nullopt;
}

// Serialises with invalid UTF-8 replaced (U+FFFD), so a reply can never throw on a string that
// slipped through; a failure of anything else still gives a fixed JSON body.
inline void json_reply(httplib::Response& res, const nlohmann::json& body, int status = 200) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  try {
    res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), "application/json");
  } catch (...) {
    res.status = 500;
    res.set_content(R"({"error":"internal error: reply could not be serialised","status":500})", "application/json");
  }
}

// The error path: the message is sanitised first (it may echo request bytes) and nothing throws.
inline void json_error(httplib::Response& res, int status, const std::string& message) noexcept {
  try {
    json_reply(res, {{"error", sanitized(message, 512)}, {"status", status}}, status);
  } catch (...) {
    res.status = status;
    res.body = R"({"error":"request failed"})";
  }
}

}  // namespace cslam::http
