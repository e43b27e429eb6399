#include "ambdiag/core/checksum.h"

namespace ambdiag {

namespace {
constexpr std::uint64_t kPrime = 1099511628211ull;
}

std::uint64_t fnv1a64(const void* data, std::size_t n_bytes, std::uint64_t state) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n_bytes; ++i) state = (state ^ p[i]) * kPrime;
  return state;
}

void fnv1a64_pair(const void* data, std::size_t n_bytes, std::uint64_t& state_a, std::uint64_t& state_b) {
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint64_t a = state_a, b = state_b;
  for (std::size_t i = 0; i < n_bytes; ++i) {
    a = (a ^ p[i]) * kPrime;
    b = (b ^ p[i]) * kPrime;
  }
  state_a = a;
  state_b = b;
}

}  // namespace ambdiag
