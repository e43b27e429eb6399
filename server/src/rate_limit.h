// Request-rate limit per caller (docs/service.md "Rate limits"): a token
// bucket per key (a token's name, or a client address for requests without
// a token) that holds at most `burst` requests and refills at `per_s`.
#pragma once

#include <chrono>
#include <mutex>
#include <string>
#include <unordered_map>

namespace ambdiag::server::detail {

class RateLimiter {
 public:
  using Clock = std::chrono::steady_clock;
  // per_s <= 0: no limit. burst < 1 is taken as 1.
  RateLimiter(double per_s, double burst);

  // Takes one request from the key's bucket: 0 when allowed, otherwise the
  // seconds until the bucket holds one again (nothing taken).
  double take(const std::string& key, Clock::time_point now = Clock::now());
  bool enabled() const { return per_s_ > 0; }
  double per_s() const { return per_s_; }
  double burst() const { return burst_; }

 private:
  struct Bucket {
    double tokens;
    Clock::time_point at;
  };
  double per_s_, burst_;
  std::mutex mu_;
  std::unordered_map<std::string, Bucket> buckets_;
};

}  // namespace ambdiag::server::detail
