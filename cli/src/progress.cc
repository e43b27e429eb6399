#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "command.h"

namespace ambdiag::cli {

namespace {
long now_ms() {
  using namespace std::chrono;
  return duration_cast<milliseconds>(steady_clock::now().time_since_epoch()).count();
}
}  // namespace

Progress::Progress(std::string label, long total) : label_(std::move(label)), total_(total) {
  const char* env = std::getenv("AMBDIAG_PROGRESS");
  enabled_ = (env && std::string(env) == "1") || ::isatty(STDERR_FILENO);
}

void Progress::update(long done) {
  if (!enabled_) return;
  const long t = now_ms();
  if (t - last_ms_ < 200 && done < total_) return;
  last_ms_ = t;
  std::fprintf(stderr, "\r%s: %ld/%ld", label_.c_str(), done, total_);
  std::fflush(stderr);
}

void Progress::finish() {
  if (!enabled_) return;
  std::fprintf(stderr, "\r%s: %ld/%ld done\n", label_.c_str(), total_, total_);
}

}  // namespace ambdiag::cli
