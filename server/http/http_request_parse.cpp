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
Parse decode_chunked(const std::string& buf, std::size_t pos, std::size_t max_body, std::string* body,
                     std::size_t* end) {
  body->clear();
  for (;;) {
    const auto eol = buf.find("\r\n", pos);
    if (eol == std::string::npos) return buf.size() - pos > 64 ? Parse::kBad : Parse::kIncomplete;
    std::string size_text = buf.substr(pos, eol - pos);
    if (const auto semi = size_text.find(';'); semi != std::string::npos) size_text.resize(semi);
    size_text = trim(size_text);
    if (size_text.empty() || size_text.size() > 8 ||
        size_text.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
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

// Splits the header block (request line first) into lines, within the header limits.
Parse header_lines(const std::string& buf, const GuardConfig& cfg, std::vector<std::string>* lines,
                   std::size_t* header_end) {
  *header_end = buf.find("\r\n\r\n");
  if (*header_end == std::string::npos) {
    if (buf.size() > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
    std::size_t count = std::count(buf.begin(), buf.end(), '\n');
    return count > cfg.max_header_count + 1 ? Parse::kHeaderTooLarge : Parse::kIncomplete;
  }
  if (*header_end + 4 > cfg.max_header_bytes) return Parse::kHeaderTooLarge;
  for (std::size_t pos = 0; pos < *header_end;) {
    const auto eol = buf.find("\r\n", pos);
    lines->push_back(buf.substr(pos, eol - pos));
    pos = eol + 2;
  }
  if (lines->empty() || lines->size() - 1 > cfg.max_header_count) return Parse::kHeaderTooLarge;
  return Parse::kComplete;
}

// What the headers say about the body and the connection, and the headers passed on to httplib.
struct HeaderScan {
  std::string normalised;  // request line and headers but Content-Length, Transfer-Encoding, Expect
  long long content_length = -1;
  bool chunked = false, keep_alive = false;
};

// One header line; kComplete if it is acceptable.
Parse scan_header(const std::string& line, HeaderScan* h, Parsed* out) {
  const auto colon = line.find(':');
  if (colon == std::string::npos || colon == 0) return Parse::kBad;
  const std::string name = lower(trim(line.substr(0, colon))), value = trim(line.substr(colon + 1));
  if (name == "content-length") {
    if (value.empty() || value.size() > 18 || value.find_first_not_of("0123456789") != std::string::npos)
      return Parse::kBad;
    const long long v = std::stoll(value);
    if (h->content_length >= 0 && v != h->content_length) return Parse::kBad;
    h->content_length = v;
    return Parse::kComplete;
  }
  if (name == "transfer-encoding") {
    if (lower(value) != "chunked") return Parse::kBad;  // nothing else is accepted
    h->chunked = true;
    return Parse::kComplete;
  }
  if (name == "expect") {
    out->expect_continue = lower(value) == "100-continue";
    return Parse::kComplete;  // the guard answers it; httplib must not
  }
  if (name == "connection") {
    const std::string v = lower(value);
    if (v.find("close") != std::string::npos) out->close = true;
    if (v.find("keep-alive") != std::string::npos) h->keep_alive = true;
  }
  h->normalised += line + "\r\n";
  return Parse::kComplete;
}

Parse scan_headers(const std::vector<std::string>& lines, HeaderScan* h, Parsed* out) {
  const std::string& request_line = lines[0];
  if (request_line.find(' ') == std::string::npos) return Parse::kBad;
  const bool http10 = request_line.size() >= 8 && request_line.compare(request_line.size() - 8, 8, "HTTP/1.0") == 0;
  h->normalised = request_line + "\r\n";
  out->close = http10;
  out->expect_continue = false;
  for (std::size_t i = 1; i < lines.size(); ++i)
    if (const Parse p = scan_header(lines[i], h, out); p != Parse::kComplete) return p;
  if (http10 && h->keep_alive) out->close = false;
  if (h->chunked && h->content_length >= 0) return Parse::kBad;  // request smuggling shape
  return Parse::kComplete;
}

// The body from `body_start` (chunked, Content-Length or none) and where the request ends.
Parse read_body(const std::string& buf, std::size_t body_start, const HeaderScan& h, const GuardConfig& cfg,
                std::string* body, std::size_t* end) {
  *end = body_start;
  if (h.chunked) return decode_chunked(buf, body_start, cfg.max_body_bytes, body, end);
  if (h.content_length > 0) {
    const std::size_t n = std::size_t(h.content_length);
    if (n > cfg.max_body_bytes) return Parse::kBodyTooLarge;
    if (buf.size() < body_start + n) return Parse::kIncomplete;
    *body = buf.substr(body_start, n);
    *end = body_start + n;
  }
  return Parse::kComplete;
}

}  // namespace

Parse parse_request(const std::string& buf, const GuardConfig& cfg, Parsed* out) {
  std::vector<std::string> lines;
  std::size_t header_end = 0;
  if (const Parse p = header_lines(buf, cfg, &lines, &header_end); p != Parse::kComplete) return p;
  HeaderScan h;
  if (const Parse p = scan_headers(lines, &h, out); p != Parse::kComplete) return p;
  std::string body;
  std::size_t end = 0;
  if (const Parse p = read_body(buf, header_end + 4, h, cfg, &body, &end); p != Parse::kComplete) return p;
  if (h.chunked || h.content_length >= 0) h.normalised += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  h.normalised += "\r\n";
  h.normalised += body;
  out->request = std::move(h.normalised);
  out->consumed = end;
  return Parse::kComplete;
}

}  // namespace cslam::http
