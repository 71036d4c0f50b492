#include "server/http/http_request_parse.h"

#include <algorithm>
#include <cctype>
#include <string>
#include <vector>

namespace cslam::http {

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

// Decodes a chunked body starting at `pos`; kIncomplete until the last chunk and trailers arrived.
Parse decode_chunked(const std::string& buf, std::size_t pos, std::size_t max_body, std::string* body, std::size_t* end) {
  body->clear();
  for (;;) {
    const auto eol = buf.find("\r\n", pos);
    if (eol == std::string::npos) return buf.size() - pos > 64 ? Parse::kBad : Parse::kIncomplete;
    std::string size_text = buf.substr(pos, eol - pos);
    if (const auto semi = size_text.find(';'); semi != std::string::npos) size_text.resize(semi);
    size_text = trim(size_text);
    if (size_text.empty() || size_text.size() > 8 || size_text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
      return Parse::kBad;
    const std::size_t n = std::stoul(size_text, nullptr, 16);
    if (body->size() + n > max_body) return Parse::kBodyTooLarge;
    pos = eol + 2;
    if (n == 0) {  // trailers until an empty line
      for (;;) {
        const auto t = buf.find("\r\n", pos);
        if (t == std::string::npos) return buf.size() - pos > 8192 ? Parse::kBad : Parse::kIncomplete;
        if (t == pos) {
          *end = t + 2;
          return Parse::kComplete;
        }
        pos = t + 2;
      }
    }
    if (buf.size() < pos + n + 2) return Parse::kIncomplete;
    if (buf.compare(pos + n, 2, "\r\n") != 0) return Parse::kBad;
    body->append(buf, pos, n);
    pos += n + 2;
  }
}

}  // namespace

Parse parse_request(const std::string& buf, const GuardConfig& cfg, Parsed* out) {
  std::size_t header_end = buf.find("\r\n\r\n");
  if (header_end == std::string::npos) {
    if (buf.size() > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
    std::size_t lines = std::count(buf.begin(), buf.end(), '\n');
    return lines > cfg.max_header_count + 1 ? Parse::kHeaderTooLarge : Parse::kIncomplete;
  }
  if (header_end + 4 > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
  std::vector<std::string> lines;
  for (std::size_t pos = 0; pos < header_end;) {
    const auto eol = buf.find("\r\n", pos);
    lines.push_back(buf.substr(pos, eol - pos));
    pos = eol + 2;
  }
  if (lines.empty() || lines.size() - 1 > cfg.max_header_count) return Parse::kHeaderTooLarge;
  const std::string& request_line = lines[0];
  if (request_line.find(' ') == std::string::npos) return Parse::kBad;
  const bool http10 = request_line.size() >= 8 && request_line.compare(request_line.size() - 8, 8, "HTTP/1.0") == 0;
  std::string normalised = request_line + "\r\n";
  long long content_length = -1;
  bool chunked = false, keep_alive_10 = false;
  out->close = http10;
  out->expect_continue = false;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto colon = lines[i].find(':');
    if (colon == std::string::npos || colon == 0) return Parse::kBad;
    const std::string name = lower(trim(lines[i].substr(0, colon))), value = trim(lines[i].substr(colon + 1));
    if (name == "content-length") {
      if (value.empty() || value.size() > 18 || value.find_first_not_of("0123456789") != std::string::npos) return Parse::kBad;
      const long long v = std::stoll(value);
      if (content_length >= 0 && v != content_length) return Parse::kBad;
      content_length = v;
      continue;
    }
    if (name == "transfer-encoding") {
      if (lower(value) != "chunked") return Parse::kBad;  // nothing else is accepted
      chunked = true;
      continue;
    }
    if (name == "expect") {
      out->expect_continue = lower(value) == "100-continue";
      continue;  // the guard answers it; httplib must not
    }
    if (name == "connection") {
      const std::string v = lower(value);
      if (v.find("close") != std::string::npos) out->close = true;
      if (v.find("keep-alive") != std::string::npos) keep_alive_10 = true;
    }
    normalised += lines[i] + "\r\n";
  }
  if (http10 && keep_alive_10) out->close = false;
  if (chunked && content_length >= 0) return Parse::kBad;  // request smuggling shape
  const std::size_t body_start = header_end + 4;
  std::string body;
  std::size_t end = body_start;
  if (chunked) {
    const Parse p = decode_chunked(buf, body_start, cfg.max_body_bytes, &body, &end);
    if (p != Parse::kComplete) return p;
  } else if (content_length > 0) {
    if (std::size_t(content_length) > cfg.max_body_bytes) return Parse::kBodyTooLarge;
    if (buf.size() < body_start + std::size_t(content_length)) return Parse::kIncomplete;
    body = buf.substr(body_start, std::size_t(content_length));
    end = body_start + std::size_t(content_length);
  }
  if (chunked || content_length >= 0) normalised += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  normalised += "\r\n";
  normalised += body;
  out->request = std::move(normalised);
  out->consumed = end;
  return Parse::kComplete;
}

}  // namespace cslam::http
