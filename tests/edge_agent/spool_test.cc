#include "ambdiag/edge_agent/spool.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "ambdiag/core/checksum.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "test_support.h"

namespace ambdiag::agent {
namespace {

namespace fs = std::filesystem;

Block make_block(int64_t seq, size_t bytes, ChecksumKind kind = SpooledHeader{}.checksum_kind) {
  Block b;
  b.seq = seq;
  b.first_frame = seq * 10;
  b.n_frames = 10;
  for (size_t i = 0; i < bytes; ++i) b.payload.push_back(static_cast<char>((seq * 31 + static_cast<int64_t>(i)) & 0xff));
  b.checksum = block_checksum(kind, b.payload.data(), b.payload.size());
  return b;
}

size_t files_in(const fs::path& dir) {
  size_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) ++n;
  return n;
}

TEST(SpoolLock, ASecondHolderOfTheFolderIsRefusedNamingItAndTheFirstPid) {
  const fs::path dir = ambdiag::testing::scratch_dir() / "spool";
  {
    const SpoolLock first(dir);
    try {
      const SpoolLock second(dir);
      ADD_FAILURE() << "a second lock on " << dir << " was granted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(dir.string()), std::string::npos) << msg;
      EXPECT_NE(msg.find("in use by another ambdiag-agent (pid " + std::to_string(::getpid()) + ")"), std::string::npos)
          << msg;
    }
  }
  // Released with its owner: the folder can be taken again.
  EXPECT_NO_THROW(SpoolLock again(dir));
}

TEST(Spool, WritesEveryBlockToDiskKeepsTheFirstInMemoryAndReadsThemBack) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  Spool spool(dir, "P-1/run a", 1 << 20, 2);
  for (int64_t s = 0; s < 5; ++s) ASSERT_TRUE(spool.put(make_block(s, 1000)));
  EXPECT_EQ(spool.memory_blocks(), 2u);
  ASSERT_NE(spool.peek(1), nullptr);  // in memory: no copy
  EXPECT_EQ(spool.peek(1)->payload, make_block(1, 1000).payload);
  EXPECT_EQ(spool.peek(2), nullptr);  // on disk only
  Block moved = make_block(5, 1000);
  ASSERT_TRUE(spool.put(std::move(moved)));
  EXPECT_EQ(spool.get(5).payload, make_block(5, 1000).payload);
  spool.erase(5);
  EXPECT_EQ(files_in(dir), 1u);  // one segment
  EXPECT_GT(spool.disk_bytes(), 5000u);
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
  Spool spool(dir, "run", 1 << 20, 1);  // every block on disk, about 3 fit
  int64_t s = 0;
  while (spool.put(make_block(s, block_bytes))) ++s;
  EXPECT_EQ(s, 3);  // 3 records of 300 KiB fit in 1 MiB, the 4th does not
  EXPECT_LE(spool.disk_bytes(), spool.limit_bytes());
  EXPECT_FALSE(spool.contains(3));
  EXPECT_FALSE(spool.has_room(block_bytes));
  spool.erase(0);  // its segment (a 300 KiB block fills one) is deleted
  EXPECT_TRUE(spool.has_room(block_bytes));
  EXPECT_TRUE(spool.put(make_block(3, block_bytes)));
}

// The limit bounds the folder, not each run: runs an earlier agent left
// behind (the server away for a long time) count, so a new run gets what is
// left, and all of it again once they are forwarded.
TEST(Spool, RunsLeftInTheFolderCountAgainstTheLimit) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  const size_t block_bytes = 300 * 1024;
  {
    Spool left(dir, "run a", 1 << 20, 1);
    left.write_header(SpooledHeader{"run a", "P-1", "{}", 1, 1000.0, 10});
    ASSERT_TRUE(left.put(make_block(0, block_bytes)));
    ASSERT_TRUE(left.put(make_block(1, block_bytes)));
  }  // the agent is gone; its run stays on disk
  Spool next(dir, "run b", 1 << 20, 1);
  next.write_header(SpooledHeader{"run b", "P-1", "{}", 1, 1000.0, 10});
  EXPECT_GT(next.folder_disk_bytes(), 2 * block_bytes);
  int64_t s = 0;
  while (next.put(make_block(s, block_bytes))) ++s;
  EXPECT_EQ(s, 1);  // 3 records of 300 KiB fit in 1 MiB, 2 are run a's
  EXPECT_LE(next.folder_disk_bytes(), next.limit_bytes());

  for (const auto& run : Spool::pending_runs(dir)) {
    std::vector<std::string> problems;
    const auto held = Spool::recover(run, 1 << 20, 1, problems);
    if (held->header()->run_id == "run a") held->remove();  // forwarded
  }
  Spool again(dir, "run c", 1 << 20, 1);
  EXPECT_EQ(again.folder_disk_bytes(), next.disk_bytes());  // run b's block only
  EXPECT_TRUE(again.put(make_block(0, block_bytes)));
  EXPECT_TRUE(again.put(make_block(1, block_bytes)));
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

SpooledHeader header_of(const std::string& run_id) {
  return SpooledHeader{run_id, "P-1", R"({"run_id": "x"})", 15, 8000.0, 10};
}

fs::path only_segment(const fs::path& run_dir) {
  for (const auto& e : fs::directory_iterator(run_dir))
    if (e.path().extension() == ".log") return e.path();
  return {};
}

// What a killed agent leaves (no destructor runs under kill -9, and the
// destructor deletes nothing) is read back whole by a new agent.
TEST(Spool, ARunSurvivesTheAgentAndIsRecoveredWhole) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  fs::path run_dir;
  {
    Spool spool(dir, "P-1/run b", 1 << 20, 1);
    spool.write_header(header_of("P-1/run b"));
    for (int64_t s = 0; s < 6; ++s) ASSERT_TRUE(spool.put(make_block(s, 700 + static_cast<size_t>(s))));
    spool.erase(0);  // acknowledged, but its segment holds others: still on disk
    spool.write_end(SpooledEnd{6, 60, 0x1234abcdull});
    run_dir = spool.folder();
  }
  ASSERT_EQ(Spool::pending_runs(dir), std::vector<fs::path>{run_dir});
  std::vector<std::string> problems;
  const auto r = Spool::recover(run_dir, 1 << 20, 1, problems);
  EXPECT_TRUE(problems.empty());
  ASSERT_TRUE(r->header() && r->end());
  EXPECT_EQ(r->header()->run_id, "P-1/run b");
  EXPECT_EQ(r->header()->n_channels, 15u);
  EXPECT_EQ(r->end()->n_blocks, 6);
  EXPECT_EQ(r->end()->checksum, 0x1234abcdull);
  // Acknowledgements within a segment are not recorded: block 0 comes back
  // and is re-sent (stored idempotently by the server).
  EXPECT_EQ(r->seqs(), (std::vector<int64_t>{0, 1, 2, 3, 4, 5}));
  for (int64_t s = 0; s < 6; ++s) EXPECT_EQ(r->get(s).payload, make_block(s, 700 + static_cast<size_t>(s)).payload);
  r->remove();
  EXPECT_FALSE(fs::exists(run_dir));
}

// A spool folder of a protocol 1.0 agent: header.json without checksum_kind,
// blocks with FNV-1a 64 checksums. A new agent recovers and verifies it with
// FNV-1a, so it forwards the run with the checksums of its blocks and end.
TEST(Spool, ASpoolOfAnEarlierAgentIsVerifiedWithFnv1a) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  fs::path run_dir;
  {
    Spool spool(dir, "P-1/old", 1 << 20, 0);
    SpooledHeader h = header_of("P-1/old");
    h.checksum_kind = ChecksumKind::fnv1a64;
    spool.write_header(h);
    for (int64_t s = 0; s < 3; ++s) ASSERT_TRUE(spool.put(make_block(s, 500, ChecksumKind::fnv1a64)));
    run_dir = spool.folder();
  }
  // What an earlier agent wrote: no checksum_kind at all.
  auto j = nlohmann::json::parse(read_file_bytes((run_dir / "header.json").string()));
  j.erase("checksum_kind");
  write_file_atomic((run_dir / "header.json").string(), j.dump());
  std::vector<std::string> problems;
  const auto r = Spool::recover(run_dir, 1 << 20, 0, problems);
  EXPECT_TRUE(problems.empty()) << problems.front();
  EXPECT_EQ(r->checksum_kind(), ChecksumKind::fnv1a64);
  EXPECT_EQ(r->seqs(), (std::vector<int64_t>{0, 1, 2}));
  EXPECT_EQ(r->get(2).checksum, fnv1a64(r->get(2).payload.data(), 500));
  // The same blocks read as xxh64 would all be refused as damaged.
  j["checksum_kind"] = "xxh64";
  write_file_atomic((run_dir / "header.json").string(), j.dump());
  problems.clear();
  EXPECT_TRUE(Spool::recover(run_dir, 1 << 20, 0, problems)->seqs().empty());
  EXPECT_EQ(problems.size(), 3u);
}

// A run of three 1000-byte blocks (records of 1048 bytes) in one segment,
// left behind as by a killed agent; returns its folder.
fs::path spool_three_blocks_and_leave() {
  Spool spool(ambdiag::testing::scratch_dir(), "run", 1 << 20, 0);
  spool.write_header(header_of("run"));
  for (int64_t s = 0; s < 3; ++s) spool.put(make_block(s, 1000));
  return spool.folder();
}

// A crash in the middle of an append leaves a torn last record: it is
// detected by its length, reported, cut off and never read back.
TEST(Spool, ATornLastBlockIsDroppedWithAClearMessage) {
  for (const size_t cut : {size_t{300}, size_t{1000 + 20}}) {  // inside the payload, inside the record header
    const fs::path run_dir = spool_three_blocks_and_leave();
    const fs::path seg = only_segment(run_dir);
    const auto whole = fs::file_size(seg);
    fs::resize_file(seg, whole - cut);
    std::vector<std::string> problems;
    const auto r = Spool::recover(run_dir, 1 << 20, 0, problems);
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_NE(problems[0].find("torn block record"), std::string::npos) << problems[0];
    EXPECT_NE(problems[0].find(seg.filename().string()), std::string::npos) << problems[0];
    EXPECT_EQ(r->seqs(), (std::vector<int64_t>{0, 1}));
    EXPECT_FALSE(r->end());
    EXPECT_EQ(fs::file_size(seg), whole / 3 * 2);  // cut back to whole records
    EXPECT_EQ(r->get(1).payload, make_block(1, 1000).payload);
  }
}

TEST(Spool, ADamagedBlockInTheMiddleIsDroppedAndTheOthersKept) {
  const fs::path run_dir = spool_three_blocks_and_leave();
  {
    std::fstream f(only_segment(run_dir), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(1048 + 48 + 10);  // block 1's payload
    f.put('\x55');
  }
  std::vector<std::string> problems;
  const auto r = Spool::recover(run_dir, 1 << 20, 0, problems);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("block 1 damaged"), std::string::npos) << problems[0];
  EXPECT_EQ(r->seqs(), (std::vector<int64_t>{0, 2}));
}

TEST(Spool, RefusesToRecoverAFolderWithoutHeader) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  fs::create_directories(dir / "stray");
  std::vector<std::string> problems;
  EXPECT_THROW(Spool::recover(dir / "stray", 1 << 20, 0, problems), InputError);
}

TEST(Spool, DeletesASegmentOnceAllItsBlocksAreAcknowledged) {
  const fs::path dir = ambdiag::testing::scratch_dir();
  Spool spool(dir, "run", 1 << 20, 0);  // segments of 128 KiB
  for (int64_t s = 0; s < 12; ++s) ASSERT_TRUE(spool.put(make_block(s, 30 * 1024)));
  const size_t segments = files_in(dir);
  EXPECT_GE(segments, 3u);
  const uint64_t before = spool.disk_bytes();
  for (int64_t s = 0; s < 5; ++s) spool.erase(s);  // covers the first segment (5 x 30 KiB > 128 KiB)
  EXPECT_EQ(files_in(dir), segments - 1);
  EXPECT_LT(spool.disk_bytes(), before);
  EXPECT_EQ(spool.get(11).payload, make_block(11, 30 * 1024).payload);
}

}  // namespace
}  // namespace ambdiag::agent
