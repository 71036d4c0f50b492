#pragma once
// The bearer-token check of the HTTP API (--http-token), with failed attempts rate limited per
// source address.
//
//  - The token is compared in constant time: SHA-256 of the presented token against SHA-256 of the
//    configured one (computed once), with CRYPTO_memcmp over the 32 bytes, so neither the position
//    of the first differing byte nor the token's length shows in the time taken.
//  - Every source address (an IPv6 address by its /64 prefix: one host usually owns the whole
//    prefix) has a token bucket of `max_failures` wrong tokens that refills over `window_s`. An
//    address whose bucket is empty is answered 429 with Retry-After *without the token being
//    checked*, even when it is right: otherwise a 200 among the 429s would still confirm a guess.
//    A request without any Authorization header is a 401 but guesses nothing and is not charged.
//  - The table holds at most `max_tracked` addresses with a partly used bucket; full buckets are
//    dropped. When the table is full of partly used buckets, every address not in it shares one
//    overflow bucket (counted in cslam_http_auth_table_full_total): memory stays bounded, and an
//    attacker with many addresses throttles the newcomers rather than growing the table.
// Thread-safe: the HTTP workers call check() concurrently.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

namespace cslam::http {

// Equal strings, compared through their SHA-256 digests with CRYPTO_memcmp: the time taken does not
// depend on where they differ or on their lengths (beyond hashing the presented one).
bool tokens_equal(std::string_view a, std::string_view b);

struct AuthConfig {
  int max_failures = 10;           // wrong tokens an address may send at once ...
  double window_s = 60;            // ... the bucket refills completely in this time
  std::size_t max_tracked = 4096;  // addresses with a partly used bucket
};

struct AuthStats {
  std::atomic<std::uint64_t> missing{0}, wrong{0}, throttled{0}, table_full{0};
};

class AuthGate {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Verdict { kOk, kMissing, kWrong, kThrottled };
  struct Result {
    Verdict verdict = Verdict::kOk;
    int retry_after_s = 0;  // kThrottled: whole seconds until one more attempt is allowed
  };

  AuthGate(const std::string& token, AuthConfig config = {});  // empty token: every request is kOk
  bool enabled() const { return enabled_; }
  // `authorization` is the request's Authorization header ("" if none); `ip` its source address.
  Result check(const std::string& ip, const std::string& authorization, Clock::time_point now = Clock::now());
  std::size_t tracked() const;  // addresses in the table (tests, /metrics)
  const AuthStats& stats() const { return stats_; }
  std::string metrics_text() const;  // cslam_http_auth_* for /metrics

 private:
  struct Bucket {
    double tokens = 0;
    Clock::time_point updated;
  };
  double capacity() const { return double(config_.max_failures); }
  void refill(Bucket& b, Clock::time_point now) const;
  Bucket* find(const std::string& key, Clock::time_point now);  // the overflow bucket if full; null if none
  void charge(const std::string& key, Clock::time_point now);
  void sweep(Clock::time_point now);

  const bool enabled_;
  const AuthConfig config_;
  unsigned char digest_[32] = {};  // SHA-256 of the token; the token itself is not kept
  mutable std::mutex mutex_;       // buckets_, overflow_, last_sweep_
  std::unordered_map<std::string, Bucket> buckets_;
  Bucket overflow_;
  Clock::time_point last_sweep_;
  AuthStats stats_;
};

// The table key of a source address: an IPv4 address as it is, an IPv6 address by its /64 prefix
// (an IPv4-mapped one as the IPv4 address), anything unparsable as it is.
std::string address_key(const std::string& ip);

}  // namespace cslam::http
