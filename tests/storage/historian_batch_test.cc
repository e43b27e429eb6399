// The historian's write batches, the end-of-run digest and schema v2
// (migration from v1) on real SQLite files.
#include <gtest/gtest.h>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::as_string;
using ambdiag::testing::checksum_of;
using ambdiag::testing::cut_chunks;
using ambdiag::testing::run_json_text;
using ambdiag::testing::samples_bytes;

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class HistorianBatchTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianBatchTest);
class HistorianDigestTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianDigestTest);

RunHeader header(const std::string& run_id, int n_channels) {
  return run_header_from_json(run_json_text(run_id, n_channels));
}

TEST_P(HistorianBatchTest, ManyCallsCommitTogetherAndARefusedCallUndoesOnlyItself) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto a = samples_bytes(400, 2, 1), b = samples_bytes(300, 3, 2);
  const auto ca = cut_chunks(a, 2, 100), cb = cut_chunks(b, 3, 100);
  auto reader = [&] { return Historian::open(path, Historian::Mode::read); };
  {
    auto batch = h.write_batch();
    h.begin_run(header("P-7/a", 2));
    h.begin_run(header("P-7/b", 3));
    h.put_chunks("P-7/a", ca);
    h.put_chunks("P-7/b", std::span(cb).subspan(0, 2));
    // A conflicting chunk (seq 0, other bytes) plus a new one: this call is
    // refused as a whole, the batch goes on.
    std::vector<std::uint8_t> other(cb[0].bytes.begin(), cb[0].bytes.end());
    other[3] ^= 1;
    const std::vector<Chunk> bad = {cb[2], {0, 0, 100, other}};
    EXPECT_THROW(h.put_chunks("P-7/b", bad), InputError);
    EXPECT_FALSE(reader().find_run("P-7/a"));  // nothing visible before the commit
    batch.commit();
  }
  auto r = reader();
  EXPECT_EQ(r.find_run("P-7/a")->received_chunks, 4);
  EXPECT_EQ(r.find_run("P-7/b")->received_chunks, 2);  // chunk 2 of the refused call rolled back
  EXPECT_EQ(r.read_samples("P-7/b"), as_string(std::span(b).subspan(0, 2 * 100 * 3 * 4)));
}

TEST_P(HistorianBatchTest, DestroyedWithoutCommitLeavesNoTrace) {
  const auto path = location();
  auto h = Historian::open(path);
  h.begin_run(header("P-7/c", 2));
  const auto a = samples_bytes(200, 2, 3);
  {
    auto batch = h.write_batch();
    h.put_chunks("P-7/c", cut_chunks(a, 2, 100));
  }
  EXPECT_EQ(h.find_run("P-7/c")->received_chunks, 0);
  EXPECT_EQ(h.read_samples("P-7/c"), "");
  // The connection is usable again, with and without a batch.
  h.put_chunks("P-7/c", cut_chunks(a, 2, 100));
  EXPECT_EQ(h.end_run("P-7/c", 200, checksum_of(a)).status, RunStatus::complete);
}

TEST_P(HistorianDigestTest, ADigestOfEveryChunkSkipsTheReadAndGivesTheSameVerdicts) {
  auto h = Historian::open(location());
  const auto a = samples_bytes(1000, 2, 4);
  h.begin_run(header("P-7/d", 2));
  h.put_chunks("P-7/d", cut_chunks(a, 2, 100));
  const HeldDigest right{10, checksum_of(a)};
  // A wrong run end is still caught with the digest.
  auto end = h.end_run("P-7/d", 1000, checksum_of(a) ^ 4u, right);
  EXPECT_TRUE(end.used_digest);
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_NE(end.reason.find("checksum mismatch"), std::string::npos) << end.reason;
  EXPECT_EQ(end.checksum_held, checksum_of(a));
  end = h.end_run("P-7/d", 1000, checksum_of(a), right);
  EXPECT_TRUE(end.used_digest);
  EXPECT_EQ(end.status, RunStatus::complete) << end.reason;
}

TEST_P(HistorianDigestTest, ADigestNotCoveringExactlyTheChunksHeldFallsBackToReading) {
  auto h = Historian::open(location());
  const auto a = samples_bytes(1000, 2, 5);
  h.begin_run(header("P-7/e", 2));
  const auto chunks = cut_chunks(a, 2, 100);
  h.put_chunks("P-7/e", chunks);
  // Covers 9 of 10 chunks (e.g. the server restarted mid-run): not used.
  const auto nine = fnv1a64(a.data(), 900 * 2 * 4);
  auto end = h.end_run("P-7/e", 1000, checksum_of(a), HeldDigest{9, nine});
  EXPECT_FALSE(end.used_digest);
  EXPECT_EQ(end.status, RunStatus::complete) << end.reason;

  // A gap: the digest cannot stand in for the missing chunk either.
  const auto b = samples_bytes(500, 2, 6);
  h.begin_run(header("P-7/f", 2));
  auto cb = cut_chunks(b, 2, 100);
  cb.erase(cb.begin() + 2);
  h.put_chunks("P-7/f", cb);
  end = h.end_run("P-7/f", 500, checksum_of(b), HeldDigest{4, 12345});
  EXPECT_FALSE(end.used_digest);
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_EQ(end.reason, "missing chunk seq 2");
}

TEST(HistorianSchema, AVersion1FileIsMigratedToTheLatestKeepingItsRuns) {
  const auto path = db_path();
  const auto a = samples_bytes(300, 2, 7);
  {
    auto h = Historian::open(path);
    h.begin_run(header("P-7/old", 2));
    h.put_chunks("P-7/old", cut_chunks(a, 2, 100));
    h.end_run("P-7/old", 300, checksum_of(a));
  }
  // Back to what migration 1 left: no monitoring table, no checksum kind of
  // the runs, user_version 1.
  downgrade_schema(path, 3);
  raw_exec(path, "DROP TABLE monitoring_snapshots; ALTER TABLE runs DROP COLUMN checksum_kind; PRAGMA user_version = 1;");
  EXPECT_THROW(Historian::open(path, Historian::Mode::read), InputError);  // readers do not migrate
  {
    auto h = Historian::open(path);  // the writer migrates
    const auto old = h.find_run("P-7/old");
    EXPECT_EQ(old->status, RunStatus::complete);
    EXPECT_FALSE(old->checksum_kind);  // ended before v3: not known
    EXPECT_EQ(h.read_samples("P-7/old"), as_string(a));
    h.begin_run(header("P-7/new", 2));
    h.put_chunks("P-7/new", cut_chunks(a, 2, 100));
    h.end_run("P-7/new", 300, checksum_of(a));
    EXPECT_EQ(h.find_run("P-7/new")->checksum_kind, ChecksumKind::fnv1a64);
  }
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM sqlite_schema WHERE name = 'monitoring_snapshots'"), 1);
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_TRUE(r.list_monitoring("P-7", 0, 10).empty());
}

}  // namespace
}  // namespace ambdiag::storage
