#include "ambdiag/core/checksum.h"

#include <bit>
#include <cstring>

namespace ambdiag {

namespace {

constexpr std::uint64_t kFnvPrime = 1099511628211ull;

// XXH64's constants (xxhash_spec.md).
constexpr std::uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full, kP3 = 0x165667B19E3779F9ull,
                        kP4 = 0x85EBCA77C2B2AE63ull, kP5 = 0x27D4EB2F165667C5ull;

static_assert(std::endian::native == std::endian::little, "the checksums read little-endian words");

std::uint64_t load64(const unsigned char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}
std::uint64_t load32(const unsigned char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
std::uint64_t xxh_round(std::uint64_t acc, std::uint64_t word) { return std::rotl(acc + word * kP2, 31) * kP1; }
std::uint64_t xxh_merge(std::uint64_t h, std::uint64_t lane) { return (h ^ xxh_round(0, lane)) * kP1 + kP4; }

}  // namespace

std::uint64_t fnv1a64(const void* data, std::size_t n_bytes, std::uint64_t state) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n_bytes; ++i) state = (state ^ p[i]) * kFnvPrime;
  return state;
}

void fnv1a64_pair(const void* data, std::size_t n_bytes, std::uint64_t& state_a, std::uint64_t& state_b) {
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint64_t a = state_a, b = state_b;
  for (std::size_t i = 0; i < n_bytes; ++i) {
    a = (a ^ p[i]) * kFnvPrime;
    b = (b ^ p[i]) * kFnvPrime;
  }
  state_a = a;
  state_b = b;
}

std::uint64_t xxh64(const void* data, std::size_t n_bytes, std::uint64_t seed) {
  const auto* p = static_cast<const unsigned char*>(data);
  const unsigned char* const end = p + n_bytes;
  std::uint64_t h;
  if (n_bytes >= 32) {
    std::uint64_t v1 = seed + kP1 + kP2, v2 = seed + kP2, v3 = seed, v4 = seed - kP1;
    for (; end - p >= 32; p += 32) {  // four independent lanes
      v1 = xxh_round(v1, load64(p));
      v2 = xxh_round(v2, load64(p + 8));
      v3 = xxh_round(v3, load64(p + 16));
      v4 = xxh_round(v4, load64(p + 24));
    }
    h = std::rotl(v1, 1) + std::rotl(v2, 7) + std::rotl(v3, 12) + std::rotl(v4, 18);
    h = xxh_merge(xxh_merge(xxh_merge(xxh_merge(h, v1), v2), v3), v4);
  } else {
    h = seed + kP5;
  }
  h += n_bytes;
  for (; end - p >= 8; p += 8) h = std::rotl(h ^ xxh_round(0, load64(p)), 27) * kP1 + kP4;
  if (end - p >= 4) {
    h = std::rotl(h ^ (load32(p) * kP1), 23) * kP2 + kP3;
    p += 4;
  }
  for (; p < end; ++p) h = std::rotl(h ^ (*p * kP5), 11) * kP1;
  h ^= h >> 33;
  h *= kP2;
  h ^= h >> 29;
  h *= kP3;
  h ^= h >> 32;
  return h;
}

const char* to_string(ChecksumKind k) { return k == ChecksumKind::xxh64 ? "xxh64" : "fnv1a64"; }

std::optional<ChecksumKind> checksum_kind_from(std::uint32_t value) {
  if (value == static_cast<std::uint32_t>(ChecksumKind::fnv1a64)) return ChecksumKind::fnv1a64;
  if (value == static_cast<std::uint32_t>(ChecksumKind::xxh64)) return ChecksumKind::xxh64;
  return std::nullopt;
}

std::optional<ChecksumKind> checksum_kind_from(const std::string& name) {
  if (name == "fnv1a64") return ChecksumKind::fnv1a64;
  if (name == "xxh64") return ChecksumKind::xxh64;
  return std::nullopt;
}

std::uint64_t run_checksum_init(ChecksumKind k) { return k == ChecksumKind::xxh64 ? 0 : kFnv1a64Init; }

BlockChecksums block_checksums(ChecksumKind k, const void* payload, std::size_t n_bytes, std::uint64_t run_before) {
  BlockChecksums r;
  if (k == ChecksumKind::xxh64) {
    r.block = xxh64(payload, n_bytes);
    const std::uint64_t le = r.block;  // little-endian host (static_assert above)
    r.run_after = xxh64(&le, sizeof le, run_before);
  } else {
    r.block = kFnv1a64Init;
    r.run_after = run_before;
    fnv1a64_pair(payload, n_bytes, r.block, r.run_after);
  }
  return r;
}

std::uint64_t block_checksum(ChecksumKind k, const void* payload, std::size_t n_bytes) {
  return k == ChecksumKind::xxh64 ? xxh64(payload, n_bytes) : fnv1a64(payload, n_bytes);
}

}  // namespace ambdiag
