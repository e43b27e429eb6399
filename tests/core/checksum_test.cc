#include <gtest/gtest.h>

#include <string>

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

}  // namespace
}  // namespace ambdiag
