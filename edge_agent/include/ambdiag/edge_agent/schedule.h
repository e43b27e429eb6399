// When the agent does what: a tick every `interval_s`, the first at
// `first_s` (seconds on the caller's clock). A tick that falls due while
// the previous work still runs is done once when it ends, not once per
// missed interval (a slow run must not cause a burst of runs).
#pragma once

#include <cmath>

namespace ambdiag::agent {

class Ticker {
 public:
  // interval_s <= 0: never due.
  Ticker(double interval_s, double first_s) : interval_s_(interval_s), next_s_(first_s) {}
  bool enabled() const { return interval_s_ > 0; }
  bool due(double now_s) const { return enabled() && now_s >= next_s_; }
  double next_s() const { return next_s_; }
  // Marks the tick due at or before now_s done; the next is the first
  // multiple of the interval after now_s.
  void done(double now_s) {
    if (!enabled()) return;
    const double missed = std::floor((now_s - next_s_) / interval_s_);
    next_s_ += (missed + 1.0) * interval_s_;
  }

 private:
  double interval_s_;
  double next_s_;
};

}  // namespace ambdiag::agent
