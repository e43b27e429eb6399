#include "ambdiag/edge_agent/spool.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ambdiag/core/checksum.h"
#include "test_support.h"

namespace ambdiag::agent {
namespace {

namespace fs = std::filesystem;

Block make_block(int64_t seq, size_t bytes) {
  Block b;
  b.seq = seq;
  b.first_frame = seq * 10;
  b.n_frames = 10;
  for (size_t i = 0; i < bytes; ++i) b.payload.push_back(static_cast<char>((seq * 31 + static_cast<int64_t>(i)) & 0xff));
  b.checksum = fnv1a64(b.payload.data(), b.payload.size());
  return b;
}

size_t files_in(const fs::path& dir) {
  size_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) ++n;
  return n;
}

TEST(Spool, KeepsFirstBlocksInMemoryThenWritesFilesAndReadsThemBack) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  Spool spool(dir, "P-1/run a", 1 << 20, 2);
  for (int64_t s = 0; s < 5; ++s) ASSERT_TRUE(spool.put(make_block(s, 1000)));
  EXPECT_EQ(spool.memory_blocks(), 2u);
  EXPECT_EQ(files_in(dir), 3u);
  EXPECT_GT(spool.disk_bytes(), 3000u);
  for (int64_t s = 0; s < 5; ++s) {
    const Block b = spool.get(s);
    EXPECT_EQ(b.payload, make_block(s, 1000).payload);
    EXPECT_EQ(b.first_frame, s * 10);
  }
  for (int64_t s = 0; s < 5; ++s) spool.erase(s);
  EXPECT_EQ(spool.size(), 0u);
  EXPECT_EQ(spool.disk_bytes(), 0u);
  EXPECT_EQ(files_in(dir), 0u);
}

TEST(Spool, RefusesBlocksBeyondItsDiskLimitAndAcceptsAgainAfterErase) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  const size_t block_bytes = 300 * 1024;
  Spool spool(dir, "run", 1 << 20, 1);  // 1 in memory, then about 3 on disk
  ASSERT_TRUE(spool.put(make_block(0, block_bytes)));
  int64_t s = 1;
  while (spool.put(make_block(s, block_bytes))) ++s;
  EXPECT_EQ(s, 4);  // 3 files of 300 KiB fit in 1 MiB, the 4th does not
  EXPECT_LE(spool.disk_bytes(), spool.limit_bytes());
  EXPECT_FALSE(spool.contains(4));
  EXPECT_FALSE(spool.has_room(block_bytes));
  spool.erase(1);
  EXPECT_TRUE(spool.has_room(block_bytes));
  EXPECT_TRUE(spool.put(make_block(4, block_bytes)));
}

TEST(Spool, DetectsADamagedSpoolFile) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  Spool spool(dir, "run", 1 << 20, 0);
  ASSERT_TRUE(spool.put(make_block(7, 4000)));
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::fstream f(e.path(), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x55');
  }
  EXPECT_THROW(spool.get(7), std::runtime_error);
}

TEST(Spool, DistinctRunIdsGetDistinctFolders) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  Spool a(dir, "P-1/x", 1 << 20, 0), b(dir, "P-1_x", 1 << 20, 0);
  ASSERT_TRUE(a.put(make_block(0, 10)));
  ASSERT_TRUE(b.put(make_block(0, 20)));
  EXPECT_EQ(a.get(0).payload.size(), 10u);
  EXPECT_EQ(b.get(0).payload.size(), 20u);
}

}  // namespace
}  // namespace ambdiag::agent
