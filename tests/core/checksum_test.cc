#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "ambdiag/core/checksum.h"

namespace ambdiag {
namespace {

// Published FNV-1a 64 test vectors (Fowler, Noll, Vo reference code).
TEST(Checksum, MatchesPublishedVectors) {
  EXPECT_EQ(fnv1a64("", 0), 0xcbf29ce484222325ull);
  EXPECT_EQ(fnv1a64("a", 1), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(fnv1a64("foobar", 6), 0x85944171f73967e8ull);
}

TEST(Checksum, ChunkedEqualsWhole) {
  const std::string s = "samples of a run, streamed in blocks";
  std::uint64_t state = kFnv1a64Init;
  for (std::size_t i = 0; i < s.size(); i += 5) state = fnv1a64(s.data() + i, std::min<std::size_t>(5, s.size() - i), state);
  EXPECT_EQ(state, fnv1a64(s.data(), s.size()));
}

TEST(Checksum, PairEqualsTwoSeparateChecksums) {
  const std::string s = "a block of a run, hashed on its own and as part of the run";
  const std::uint64_t run_before = fnv1a64("earlier blocks", 14);
  std::uint64_t block = kFnv1a64Init, run = run_before;
  fnv1a64_pair(s.data(), s.size(), block, run);
  EXPECT_EQ(block, fnv1a64(s.data(), s.size()));
  EXPECT_EQ(run, fnv1a64(s.data(), s.size(), run_before));
  EXPECT_NE(block, run);
}

TEST(Checksum, DetectsSwappedBlocks) {
  EXPECT_NE(fnv1a64("abcdef", 6), fnv1a64("defabc", 6));
}

// XXH64 of the reference library (libxxhash 0.8.1, XXH64(data, n, seed)),
// computed independently: the empty string and "abc" with seed 0 (xxHash's
// published values), and prefixes of a fixed byte pattern that cover every
// tail path (no 32-byte stripe, 8-, 4- and 1-byte tails, a 30 KiB block).
TEST(Checksum, Xxh64MatchesTheReferenceLibrary) {
  EXPECT_EQ(xxh64("", 0), 0xef46db3751d8e999ull);
  EXPECT_EQ(xxh64("abc", 3), 0x44bc2cf5ad770999ull);
  std::vector<unsigned char> b(30720);
  for (std::size_t i = 0; i < b.size(); ++i) b[i] = static_cast<unsigned char>(i * 131 + 7);
  const std::pair<std::size_t, std::uint64_t> ref[] = {
      {0, 0x4be1d406981cfd3bull},  {1, 0x3f1cd0f837fa3c76ull},  {3, 0xec71b28f75d61531ull},
      {4, 0x45976f2a2cb4ff55ull},  {7, 0xd9177e418dfa6cecull},  {8, 0xb8864231188eed9bull},
      {31, 0xfca8563dca00e6fdull}, {32, 0x92941523480ebe4bull}, {33, 0x7bf8210a6de9d5e5ull},
      {100, 0x955628cc999db9e6ull}, {30720, 0x5284bd9dfc2f2416ull}};
  for (const auto& [n, want] : ref) EXPECT_EQ(xxh64(b.data(), n, 5), want) << n << " bytes";
}

TEST(Checksum, BlockChecksumsOfEitherKindAgreeWithTheirDefinition) {
  const std::string blocks[] = {"first block of a run", "the second one", "and a third, odd-sized."};
  for (const ChecksumKind k : {ChecksumKind::fnv1a64, ChecksumKind::xxh64}) {
    std::uint64_t run = run_checksum_init(k);
    std::string all;
    for (const auto& b : blocks) {
      const BlockChecksums c = block_checksums(k, b.data(), b.size(), run);
      EXPECT_EQ(c.block, block_checksum(k, b.data(), b.size()));
      run = c.run_after;
      all += b;
    }
    if (k == ChecksumKind::fnv1a64) {
      EXPECT_EQ(run, fnv1a64(all.data(), all.size()));  // independent of the cut into blocks
    } else {
      std::uint64_t chain = 0;  // run_{k+1} = XXH64(le64(block_k), seed run_k)
      for (const auto& b : blocks) {
        const std::uint64_t h = xxh64(b.data(), b.size());
        chain = xxh64(&h, 8, chain);
      }
      EXPECT_EQ(run, chain);
    }
  }
}

TEST(Checksum, Xxh64RunChecksumDetectsSwappedAndDamagedBlocks) {
  const auto run_of = [](std::initializer_list<std::string> blocks) {
    std::uint64_t run = run_checksum_init(ChecksumKind::xxh64);
    for (const auto& b : blocks) run = block_checksums(ChecksumKind::xxh64, b.data(), b.size(), run).run_after;
    return run;
  };
  const std::uint64_t ok = run_of({"block zero", "block one"});
  EXPECT_NE(ok, run_of({"block one", "block zero"}));
  EXPECT_NE(ok, run_of({"block zero", "block onf"}));
  EXPECT_NE(ok, run_of({"block zero"}));
  EXPECT_NE(ok, run_of({"block zero", "block one", "block one"}));
}

TEST(Checksum, KindsHaveStableProtocolValuesAndNames) {
  EXPECT_EQ(checksum_kind_from(0u), ChecksumKind::fnv1a64);
  EXPECT_EQ(checksum_kind_from(1u), ChecksumKind::xxh64);
  EXPECT_FALSE(checksum_kind_from(2u));
  EXPECT_EQ(checksum_kind_from(std::string("xxh64")), ChecksumKind::xxh64);
  EXPECT_EQ(checksum_kind_from(std::string(to_string(ChecksumKind::fnv1a64))), ChecksumKind::fnv1a64);
  EXPECT_FALSE(checksum_kind_from(std::string("crc32")));
}

}  // namespace
}  // namespace ambdiag
