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

TEST(Checksum, DetectsSwappedBlocks) {
  EXPECT_NE(fnv1a64("abcdef", 6), fnv1a64("defabc", 6));
}

}  // namespace
}  // namespace ambdiag
