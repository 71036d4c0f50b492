#include "server/http/auth_gate.h"

#include <arpa/inet.h>
#include <openssl/crypto.h>
#include <openssl/sha.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <sstream>

namespace cslam::http {
namespace {

void sha256(std::string_view s, unsigned char out[32]) {
  SHA256(reinterpret_cast<const unsigned char*>(s.data()), s.size(), out);
}

// The one comparison of a presented token: its digest against a digest, in constant time.
bool matches(std::string_view presented, const unsigned char digest[32]) {
  unsigned char d[32];
  sha256(presented, d);
  return CRYPTO_memcmp(d, digest, sizeof d) == 0;
}

// The token of "Bearer TOKEN" (scheme case-insensitive, RFC 6750); false if the header is no bearer.
bool bearer_token(const std::string& header, std::string_view* token) {
  static constexpr std::string_view kScheme = "bearer ";
  if (header.size() < kScheme.size()) return false;
  for (std::size_t i = 0; i < kScheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(header[i])) != kScheme[i]) return false;
  *token = std::string_view(header).substr(kScheme.size());
  return true;
}

}  // namespace

bool tokens_equal(std::string_view a, std::string_view b) {
  unsigned char db[32];
  sha256(b, db);
  return matches(a, db);
}

std::string address_key(const std::string& ip) {
  in6_addr a6{};
  if (inet_pton(AF_INET6, ip.c_str(), &a6) != 1) return ip;  // IPv4 (or not an address): as it is
  static const unsigned char kMapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
  char text[INET6_ADDRSTRLEN] = "";
  if (std::memcmp(a6.s6_addr, kMapped, sizeof kMapped) == 0) {
    inet_ntop(AF_INET, a6.s6_addr + 12, text, sizeof text);
    return text;
  }
  std::memset(a6.s6_addr + 8, 0, 8);
  inet_ntop(AF_INET6, &a6, text, sizeof text);
  return std::string(text) + "/64";
}

AuthGate::AuthGate(const std::string& token, AuthConfig config) : enabled_(!token.empty()), config_(config) {
  sha256(token, digest_);
  overflow_.tokens = capacity();
}

void AuthGate::refill(Bucket& b, Clock::time_point now) const {
  const double elapsed = std::chrono::duration<double>(now - b.updated).count();
  if (elapsed > 0) b.tokens = std::min(capacity(), b.tokens + elapsed * capacity() / config_.window_s);
  b.updated = std::max(b.updated, now);
}

void AuthGate::sweep(Clock::time_point now) {
  last_sweep_ = now;
  for (auto it = buckets_.begin(); it != buckets_.end();) {
    refill(it->second, now);
    it = it->second.tokens >= capacity() ? buckets_.erase(it) : std::next(it);
  }
}

AuthGate::Bucket* AuthGate::find(const std::string& key, Clock::time_point now) {
  if (auto it = buckets_.find(key); it != buckets_.end()) return &it->second;
  if (buckets_.size() < config_.max_tracked) return nullptr;
  if (now - last_sweep_ >= std::chrono::seconds(1)) sweep(now);  // at most once a second under a flood
  return buckets_.size() < config_.max_tracked ? nullptr : &overflow_;
}

void AuthGate::charge(const std::string& key, Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mutex_);
  Bucket* b = find(key, now);
  if (b == &overflow_) ++stats_.table_full;
  if (!b) {
    b = &buckets_[key];
    b->tokens = capacity();
    b->updated = now;
  }
  refill(*b, now);
  b->tokens = std::max(0.0, b->tokens - 1);
}

AuthGate::Result AuthGate::check(const std::string& ip, const std::string& authorization, Clock::time_point now) {
  if (!enabled_) return {};
  const std::string key = address_key(ip);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (Bucket* b = find(key, now)) {
      refill(*b, now);
      if (b->tokens < 1) {  // refused before the token is looked at
        ++stats_.throttled;
        const double wait_s = (1 - b->tokens) * config_.window_s / capacity();
        return {Verdict::kThrottled, std::max(1, int(std::ceil(wait_s)))};
      }
    }
  }
  std::string_view presented;
  if (authorization.empty() || !bearer_token(authorization, &presented)) {
    ++stats_.missing;
    return {Verdict::kMissing, 0};
  }
  if (matches(presented, digest_)) return {};
  ++stats_.wrong;
  charge(key, now);
  return {Verdict::kWrong, 0};
}

std::size_t AuthGate::tracked() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return buckets_.size();
}

std::string AuthGate::metrics_text() const {
  std::ostringstream o;
  o << "# HELP cslam_http_auth_failures_total API requests refused for their bearer token (401), by reason.\n"
       "# TYPE cslam_http_auth_failures_total counter\n"
    << "cslam_http_auth_failures_total{reason=\"missing\"} " << stats_.missing << "\n"
    << "cslam_http_auth_failures_total{reason=\"wrong\"} " << stats_.wrong << "\n"
    << "# HELP cslam_http_auth_throttled_total API requests refused (429) because their address sent too many "
       "wrong tokens.\n"
       "# TYPE cslam_http_auth_throttled_total counter\n"
    << "cslam_http_auth_throttled_total " << stats_.throttled << "\n"
    << "# HELP cslam_http_auth_table_full_total Wrong tokens charged to the shared overflow bucket (address table "
       "full).\n"
       "# TYPE cslam_http_auth_table_full_total counter\n"
    << "cslam_http_auth_table_full_total " << stats_.table_full << "\n"
    << "# HELP cslam_http_auth_addresses Addresses with a partly used failure bucket.\n"
       "# TYPE cslam_http_auth_addresses gauge\n"
    << "cslam_http_auth_addresses " << tracked() << "\n";
  return o.str();
}

}  // namespace cslam::http
