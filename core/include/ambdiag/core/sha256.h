// SHA-256 (FIPS 180-4, section 6.2): the digest the historian keeps of API
// tokens instead of the tokens themselves. Not for bulk data (about 15
// cycles a byte); the run checksums are in checksum.h.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace ambdiag {

using Sha256Digest = std::array<std::uint8_t, 32>;

// Incremental: update() with the message in any cut, then digest() once.
class Sha256 {
 public:
  Sha256();
  void update(const void* data, std::size_t n_bytes);
  void update(std::string_view s) { update(s.data(), s.size()); }
  // Pads and returns the digest; the object is then spent (reset() to reuse).
  Sha256Digest digest();
  void reset();

 private:
  void compress(const std::uint8_t* block);
  std::array<std::uint32_t, 8> h_{};
  std::array<std::uint8_t, 64> buf_{};
  std::size_t buf_len_ = 0;
  std::uint64_t total_bytes_ = 0;
};

Sha256Digest sha256(std::string_view bytes);
// Lower-case hex, 64 digits.
std::string to_hex(const Sha256Digest& d);

}  // namespace ambdiag
