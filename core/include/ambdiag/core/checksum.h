// Checksums that tie a streamed run to what was recorded. Not cryptographic:
// they catch loss, duplication, reordering and bit errors.
//
// Two kinds, told apart by the stream protocol (docs/streaming.md):
//  - fnv1a64 (protocol 1.0): FNV-1a 64 over the bytes. A block's checksum is
//    FNV-1a of its payload; the run's is FNV-1a of the whole samples.f32 in
//    sample order, independent of how it was cut into blocks. Byte-serial:
//    one dependent multiply per byte, about 4 CPU cycles a byte.
//  - xxh64 (protocol 1.1): a block's checksum is XXH64 (seed 0) of its
//    payload (Yann Collet's xxHash64, specified in xxhash_spec.md of the
//    xxHash project: four independent multiply-rotate lanes over 8-byte
//    little-endian words, about 0.5 cycles a byte here); the run's is the
//    chain of its blocks' checksums in seq order,
//        run_0 = 0,  run_{k+1} = XXH64(8 little-endian bytes of block_k, seed = run_k),
//    so it is computed from the block checksums alone, without a second
//    pass over the samples, and depends on the cut into blocks (which the
//    run end's block count fixes).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace ambdiag {

inline constexpr std::uint64_t kFnv1a64Init = 14695981039346656037ull;

// Continues a running checksum over more bytes: feeding a run chunk by chunk
// gives the same value as feeding it in one call.
std::uint64_t fnv1a64(const void* data, std::size_t n_bytes, std::uint64_t state = kFnv1a64Init);

// Continues two running checksums over the same bytes in one pass, e.g. a
// block's own (from kFnv1a64Init) and its run's. Same values as two fnv1a64
// calls at about the cost of one: FNV is a chain of dependent multiplies, and
// two independent chains run side by side in the CPU.
void fnv1a64_pair(const void* data, std::size_t n_bytes, std::uint64_t& state_a, std::uint64_t& state_b);

// XXH64 of the bytes with the seed (the reference algorithm's value).
std::uint64_t xxh64(const void* data, std::size_t n_bytes, std::uint64_t seed = 0);

// Values are the stream protocol's (SampleBlock/RunEnd.checksum_kind): never renumber.
enum class ChecksumKind : std::uint32_t { fnv1a64 = 0, xxh64 = 1 };

const char* to_string(ChecksumKind k);
// The kind with this protocol value or name, or nothing if unknown.
std::optional<ChecksumKind> checksum_kind_from(std::uint32_t value);
std::optional<ChecksumKind> checksum_kind_from(const std::string& name);

// A run's checksum before its first block.
std::uint64_t run_checksum_init(ChecksumKind k);

// One block of a run: its own checksum, and the run's after it given the
// run's before it (only meaningful when the block follows the one that gave
// `run_before`). One pass over the payload for either kind.
struct BlockChecksums {
  std::uint64_t block = 0, run_after = 0;
};
BlockChecksums block_checksums(ChecksumKind k, const void* payload, std::size_t n_bytes, std::uint64_t run_before);
// A block's own checksum only.
std::uint64_t block_checksum(ChecksumKind k, const void* payload, std::size_t n_bytes);

}  // namespace ambdiag
