#include "ambdiag/core/checksum.h"

namespace ambdiag {

std::uint64_t fnv1a64(const void* data, std::size_t n_bytes, std::uint64_t state) {
  constexpr std::uint64_t kPrime = 1099511628211ull;
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n_bytes; ++i) state = (state ^ p[i]) * kPrime;
  return state;
}

}  // namespace ambdiag
