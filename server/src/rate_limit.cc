#include "rate_limit.h"

#include <algorithm>

namespace ambdiag::server::detail {

namespace {
// Past this many keys, the buckets that have refilled (callers idle for
// burst / per_s) are forgotten: they would start full anyway. Bounds the
// memory that many client addresses could take.
constexpr size_t kSweepAbove = 10000;
}  // namespace

RateLimiter::RateLimiter(double per_s, double burst) : per_s_(per_s), burst_(std::max(1.0, burst)) {}

double RateLimiter::take(const std::string& key, Clock::time_point now) {
  if (per_s_ <= 0) return 0;
  const auto refilled = [&](const Bucket& b) {
    return std::min(burst_, b.tokens + per_s_ * std::chrono::duration<double>(now - b.at).count());
  };
  std::lock_guard l(mu_);
  if (buckets_.size() > kSweepAbove)
    std::erase_if(buckets_, [&](const auto& kv) { return refilled(kv.second) >= burst_; });
  auto [it, fresh] = buckets_.try_emplace(key, Bucket{burst_, now});
  Bucket& b = it->second;
  b.tokens = fresh ? burst_ : refilled(b);
  b.at = now;
  if (b.tokens >= 1.0) {
    b.tokens -= 1.0;
    return 0;
  }
  return (1.0 - b.tokens) / per_s_;
}

}  // namespace ambdiag::server::detail
