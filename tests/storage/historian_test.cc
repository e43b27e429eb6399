// The historian on both backends (a real SQLite file, a real PostgreSQL
// schema): idempotency, run-end checks, bad input refused; and what is
// SQLite's own: the file's schema, a file that is not a database.
#include "ambdiag/storage/historian.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <fstream>
#include <random>

#include "ambdiag/core/error.h"
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

class HistorianTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianTest);

struct TestRun {
  RunHeader header;
  std::vector<std::uint8_t> bytes;
  int n_channels;
};

TestRun make_run(const std::string& run_id, std::int64_t n_frames, int n_channels, unsigned seed,
             const std::string& pump = "P-7") {
  return {run_header_from_json(run_json_text(run_id, n_channels, pump)), samples_bytes(n_frames, n_channels, seed),
          n_channels};
}

TEST(Historian, MigratesAnEmptyFileToTheLatestSchemaAndReopens) {
  const auto path = db_path();
  { auto h = Historian::open(path); }
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
  for (const char* t : {"pumps", "runs", "channels", "sample_chunks", "frfs", "features", "alarms", "jobs"}) {
    const std::string sql = std::string("SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = '") + t + "'";
    EXPECT_EQ(raw_query_int(path, sql.c_str()), 1) << t;
  }
  auto h = Historian::open(path);  // re-open: no migration runs twice
  EXPECT_EQ(h.count_runs(), 0);
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_TRUE(r.list_pumps().empty());
}

TEST_P(HistorianTest, DataSurvivesReopening) {
  const auto path = location();
  const TestRun run = make_run("P-7/a", 1000, 3, 1);
  {
    auto h = Historian::open(path);
    h.begin_run(run.header);
    const auto chunks = cut_chunks(run.bytes, 3, 128);
    h.put_chunks(run.header.run_id, chunks);
    EXPECT_EQ(h.end_run(run.header.run_id, 1000, checksum_of(run.bytes)).status, RunStatus::complete);
  }
  auto h = Historian::open(path, Historian::Mode::read);
  const auto info = h.find_run("P-7/a");
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, RunStatus::complete);
  EXPECT_EQ(info->received_frames, 1000);
  EXPECT_EQ(info->header_json, run.header.header_json);
  EXPECT_EQ(h.read_samples("P-7/a"), as_string(run.bytes));
}

TEST_P(HistorianTest, BeginRunIsIdempotentAndRefusesAnotherHeaderUnderTheSameId) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/a", 10, 2, 1);
  h.begin_run(run.header);
  h.begin_run(run.header);
  // The same JSON written with other whitespace is the same header.
  h.begin_run(run_header_from_json(nlohmann::json::parse(run.header.header_json).dump()));
  EXPECT_EQ(h.count_runs(), 1);
  const auto other = run_header_from_json(run_json_text("P-7/a", 2, "P-7", 1500.0));
  EXPECT_THROW(h.begin_run(other), InputError);
  EXPECT_EQ(h.find_run("P-7/a")->speed_rpm, 3000.0);
}

TEST_P(HistorianTest, StoresChunksArrivingOutOfOrderAndReadsThemBackInOrder) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/b", 5000, 4, 2);
  h.begin_run(run.header);
  auto chunks = cut_chunks(run.bytes, 4, 97);  // last chunk shorter
  std::mt19937 rng(5);
  std::shuffle(chunks.begin(), chunks.end(), rng);
  // Three batches of shuffled chunks.
  const size_t third = chunks.size() / 3;
  std::span<const Chunk> all(chunks);
  for (auto part : {all.subspan(0, third), all.subspan(third, third), all.subspan(2 * third)})
    EXPECT_EQ(h.put_chunks("P-7/b", part).stored, static_cast<std::int64_t>(part.size()));
  const auto end = h.end_run("P-7/b", 5000, checksum_of(run.bytes));
  EXPECT_EQ(end.status, RunStatus::complete) << end.reason;
  EXPECT_EQ(h.read_samples("P-7/b"), as_string(run.bytes));
}

TEST_P(HistorianTest, DuplicateChunksAreCountedAndStoredOnce) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/c", 600, 3, 3);
  h.begin_run(run.header);
  const auto chunks = cut_chunks(run.bytes, 3, 100);
  EXPECT_EQ(h.put_chunks("P-7/c", std::span(chunks).subspan(0, 4)).stored, 4);
  const auto again = h.put_chunks("P-7/c", chunks);  // 4 duplicates, 2 new
  EXPECT_EQ(again.stored, 2);
  EXPECT_EQ(again.duplicates, 4);
  const auto info = h.find_run("P-7/c");
  EXPECT_EQ(info->received_chunks, 6);
  EXPECT_EQ(info->received_frames, 600);
  EXPECT_EQ(info->duplicate_chunks, 4);
  EXPECT_EQ(h.end_run("P-7/c", 600, checksum_of(run.bytes)).status, RunStatus::complete);
  EXPECT_EQ(h.read_samples("P-7/c"), as_string(run.bytes));
}

TEST_P(HistorianTest, DuplicateSeqWithOtherBytesIsRefusedAndTheBatchLeavesNoTrace) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/d", 300, 2, 4);
  h.begin_run(run.header);
  auto chunks = cut_chunks(run.bytes, 2, 100);
  h.put_chunks("P-7/d", std::span(chunks).subspan(0, 1));
  std::vector<std::uint8_t> altered(chunks[0].bytes.begin(), chunks[0].bytes.end());
  altered[17] ^= 0x01;
  std::vector<Chunk> batch = {chunks[1], chunks[2], {0, 0, 100, altered}};
  EXPECT_THROW(h.put_chunks("P-7/d", batch), InputError);
  const auto info = h.find_run("P-7/d");
  EXPECT_EQ(info->received_chunks, 1);  // chunks 1 and 2 of the refused batch were rolled back
  EXPECT_EQ(h.read_samples("P-7/d"), as_string(chunks[0].bytes));
}

TEST_P(HistorianTest, RefusesChunksOfWrongSizeUnknownRunsAndNegativeFields) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/e", 100, 3, 5);
  h.begin_run(run.header);
  const auto chunks = cut_chunks(run.bytes, 3, 50);
  const std::span<const std::uint8_t> b = chunks[0].bytes;
  const std::vector<Chunk> wrong_size = {{0, 0, 50, b.subspan(0, b.size() - 4)}};
  const std::vector<Chunk> wrong_frames = {{0, 0, 49, b}};
  const std::vector<Chunk> negative_seq = {{-1, 0, 50, b}};
  const std::vector<Chunk> negative_frame = {{0, -50, 50, b}};
  const std::vector<Chunk> zero_frames = {{0, 0, 0, {}}};
  for (const auto* bad : {&wrong_size, &wrong_frames, &negative_seq, &negative_frame, &zero_frames})
    EXPECT_THROW(h.put_chunks("P-7/e", *bad), InputError);
  EXPECT_THROW(h.put_chunks("P-7/nope", chunks), InputError);
  EXPECT_THROW(h.end_run("P-7/nope", 100, 0), InputError);
  EXPECT_THROW(h.read_samples("P-7/nope"), InputError);
  EXPECT_THROW(h.end_run("P-7/e", -1, 0), InputError);
  EXPECT_EQ(h.find_run("P-7/e")->received_chunks, 0);
  try {
    h.put_chunks("P-7/e", wrong_size);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bytes"), std::string::npos) << e.what();
  }
}

TEST_P(HistorianTest, ChecksumMismatchMarksTheRunIncompleteWithTheReason) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/f", 400, 2, 6);
  h.begin_run(run.header);
  h.put_chunks("P-7/f", cut_chunks(run.bytes, 2, 64));
  const auto end = h.end_run("P-7/f", 400, checksum_of(run.bytes) ^ 1u);
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_NE(end.reason.find("checksum"), std::string::npos) << end.reason;
  EXPECT_EQ(end.checksum_held, checksum_of(run.bytes));
  const auto info = h.find_run("P-7/f");
  EXPECT_EQ(info->status, RunStatus::incomplete);
  EXPECT_EQ(info->status_reason, end.reason);
  EXPECT_EQ(info->expected_checksum, checksum_of(run.bytes) ^ 1u);
  EXPECT_EQ(info->checksum_kind, ChecksumKind::fnv1a64);
}

TEST_P(HistorianTest, TheRunEndsChecksumKindIsKept) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/k", 400, 2, 6);
  h.begin_run(run.header);
  h.put_chunks("P-7/k", cut_chunks(run.bytes, 2, 64));
  EXPECT_FALSE(h.find_run("P-7/k")->checksum_kind);  // no end yet
  h.end_run("P-7/k", 400, 12345u, std::nullopt, ChecksumKind::xxh64);
  EXPECT_EQ(h.find_run("P-7/k")->checksum_kind, ChecksumKind::xxh64);
  EXPECT_EQ(h.find_run("P-7/k")->expected_checksum, 12345u);
}

TEST_P(HistorianTest, MissingChunkMarksIncompleteAndALateChunkCompletesTheRun) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/g", 1000, 2, 7);
  h.begin_run(run.header);
  auto chunks = cut_chunks(run.bytes, 2, 100);
  const Chunk missing = chunks[4];
  chunks.erase(chunks.begin() + 4);
  h.put_chunks("P-7/g", chunks);
  const auto end = h.end_run("P-7/g", 1000, checksum_of(run.bytes));
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_NE(end.reason.find("missing chunk seq 4"), std::string::npos) << end.reason;
  EXPECT_EQ(end.frames_held, 900);
  // The agent's spool sends the chunk late; the run end checked again.
  h.put_chunks("P-7/g", std::span(&missing, 1));
  EXPECT_EQ(h.end_run("P-7/g", 1000, checksum_of(run.bytes)).status, RunStatus::complete);
  EXPECT_EQ(h.read_samples("P-7/g"), as_string(run.bytes));
}

TEST_P(HistorianTest, MissingTailAndNonContiguousFramesAreReported) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/h", 1000, 2, 8);
  h.begin_run(run.header);
  auto chunks = cut_chunks(run.bytes, 2, 100);
  h.put_chunks("P-7/h", std::span(chunks).subspan(0, 9));  // last chunk never came
  auto end = h.end_run("P-7/h", 1000, checksum_of(run.bytes));
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_NE(end.reason.find("missing frames: 900 held"), std::string::npos) << end.reason;

  const TestRun run2 = make_run("P-7/i", 200, 2, 9);
  h.begin_run(run2.header);
  auto c2 = cut_chunks(run2.bytes, 2, 100);
  c2[1].first_frame = 101;  // a frame lost between the chunks
  h.put_chunks("P-7/i", c2);
  end = h.end_run("P-7/i", 200, checksum_of(run2.bytes));
  EXPECT_EQ(end.status, RunStatus::incomplete);
  EXPECT_NE(end.reason.find("starts at frame 101, expected 100"), std::string::npos) << end.reason;
}

TEST_P(HistorianTest, CompleteRunsAcceptDuplicatesButNoNewChunksOrOtherEnds) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/j", 300, 2, 10);
  h.begin_run(run.header);
  const auto chunks = cut_chunks(run.bytes, 2, 100);
  h.put_chunks("P-7/j", chunks);
  ASSERT_EQ(h.end_run("P-7/j", 300, checksum_of(run.bytes)).status, RunStatus::complete);
  EXPECT_EQ(h.put_chunks("P-7/j", chunks).duplicates, 3);
  EXPECT_EQ(h.end_run("P-7/j", 300, checksum_of(run.bytes)).status, RunStatus::complete);  // redelivered end
  const auto extra = samples_bytes(10, 2, 11);
  const std::vector<Chunk> more = {{3, 300, 10, extra}};
  EXPECT_THROW(h.put_chunks("P-7/j", more), InputError);
  EXPECT_THROW(h.end_run("P-7/j", 310, 0), InputError);
  EXPECT_EQ(h.mark_incomplete("P-7/j", "agent gone"), RunStatus::complete);
  EXPECT_EQ(h.find_run("P-7/j")->status, RunStatus::complete);
}

TEST_P(HistorianTest, MarkIncompleteRecordsTheReason) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/k", 100, 2, 12);
  h.begin_run(run.header);
  EXPECT_EQ(h.find_run("P-7/k")->status, RunStatus::receiving);
  EXPECT_EQ(h.mark_incomplete("P-7/k", "no data for 30 s"), RunStatus::incomplete);
  const auto info = h.find_run("P-7/k");
  EXPECT_EQ(info->status, RunStatus::incomplete);
  EXPECT_EQ(info->status_reason, "no data for 30 s");
  EXPECT_THROW(h.mark_incomplete("P-7/k", ""), InputError);
  EXPECT_THROW(h.mark_incomplete("P-7/zz", "x"), InputError);
}

TEST_P(HistorianTest, ListsPumpsWithRunCountsAndRunsByStartTime) {
  auto h = Historian::open(location());
  for (const auto& [pump, run_id, started] :
       {std::tuple{"P-1", "P-1/r2", "2026-01-02T00:00:00Z"}, {"P-1", "P-1/r1", "2026-01-01T00:00:00Z"},
        {"P-2", "P-2/r1", "2026-01-03T00:00:00Z"}}) {
    auto j = nlohmann::json::parse(run_json_text(run_id, 2, pump));
    j["started_at"] = started;
    h.begin_run(run_header_from_json(j.dump()));
  }
  const auto pumps = h.list_pumps();
  ASSERT_EQ(pumps.size(), 2u);
  EXPECT_EQ(pumps[0].pump_id, "P-1");
  EXPECT_EQ(pumps[0].n_runs, 2);
  EXPECT_EQ(pumps[0].last_run_id, "P-1/r2");
  EXPECT_EQ(pumps[1].n_runs, 1);
  const auto runs = h.list_runs("P-1");
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].run_id, "P-1/r1");
  EXPECT_EQ(runs[1].run_id, "P-1/r2");
  EXPECT_TRUE(h.list_runs("P-9").empty());
  EXPECT_FALSE(h.find_pump("P-9"));
  EXPECT_EQ(h.find_pump("P-2")->last_started_at, "2026-01-03T00:00:00Z");
}

TEST_P(HistorianTest, AReaderSeesWhatTheWriterCommittedAndCannotWrite) {
  const auto path = location();
  auto w = Historian::open(path);
  auto r = Historian::open(path, Historian::Mode::read);
  const TestRun run = make_run("P-7/l", 200, 2, 13);
  w.begin_run(run.header);
  EXPECT_EQ(r.find_run("P-7/l")->status, RunStatus::receiving);
  {
    auto snap = r.snapshot();  // the reader's view stays put while the writer goes on
    EXPECT_EQ(r.find_run("P-7/l")->received_chunks, 0);
    w.put_chunks("P-7/l", cut_chunks(run.bytes, 2, 100));
    EXPECT_EQ(r.find_run("P-7/l")->received_chunks, 0);
    EXPECT_EQ(r.read_samples("P-7/l"), "");
  }
  EXPECT_EQ(r.find_run("P-7/l")->received_chunks, 2);
  EXPECT_THROW(r.begin_run(run.header), std::logic_error);
}

TEST_P(HistorianTest, StreamSamplesStopsWhenTheSinkSaysSo) {
  auto h = Historian::open(location());
  const TestRun run = make_run("P-7/m", 1000, 2, 14);
  h.begin_run(run.header);
  h.put_chunks("P-7/m", cut_chunks(run.bytes, 2, 100));
  int calls = 0;
  EXPECT_FALSE(h.stream_samples("P-7/m", [&](std::span<const std::uint8_t>) { return ++calls < 3; }));
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(h.read_samples("P-7/m"), as_string(run.bytes));  // the connection is usable afterwards
}

TEST(Historian, RefusesAFileThatIsNotADatabase) {
  const auto path = db_path();
  std::ofstream(path, std::ios::binary) << std::string(8192, 'x');
  try {
    Historian::open(path);
    FAIL() << "garbage accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not an SQLite database"), std::string::npos) << e.what();
  }
}

TEST(Historian, RefusesACorruptDatabase) {
  const auto path = db_path();
  {
    auto h = Historian::open(path);
    const TestRun run = make_run("P-7/n", 4000, 4, 15);
    h.begin_run(run.header);
    h.put_chunks("P-7/n", cut_chunks(run.bytes, 4, 100));
  }
  raw_exec(path, "PRAGMA wal_checkpoint(TRUNCATE)");
  const auto page = static_cast<size_t>(raw_query_int(path, "PRAGMA page_size"));
  {
    // Overwrite pages 2.. with garbage; the header page stays valid.
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(page));
    const std::string junk(page * 8, '\x5a');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  EXPECT_THROW(
      {
        auto h = Historian::open(path);
        h.list_pumps();
        h.read_samples("P-7/n");
      },
      InputError);
}

TEST(Historian, RefusesANewerSchemaAndAForeignDatabase) {
  const auto path = db_path();
  { auto h = Historian::open(path); }
  raw_exec(path, ("PRAGMA user_version = " + std::to_string(Historian::schema_version() + 1)).c_str());
  try {
    Historian::open(path);
    FAIL() << "newer schema accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("newer than this program"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Historian::open(path, Historian::Mode::read), InputError);

  const auto other = (ambdiag::testing::scratch_dir() / "other.db").string();
  raw_exec(other, "CREATE TABLE t (x INTEGER)");
  EXPECT_THROW(Historian::open(other), InputError);
  raw_exec(other, "PRAGMA application_id = 1234");
  EXPECT_THROW(Historian::open(other), InputError);
  EXPECT_EQ(raw_query_int(other, "SELECT count(*) FROM sqlite_schema"), 1);  // left untouched
}

TEST(Historian, AReaderRefusesAMissingFile) {
  EXPECT_THROW(Historian::open(db_path() + ".missing", Historian::Mode::read), InputError);
}

TEST_P(HistorianTest, RefusesAHeaderWhoseFieldsDisagreeWithItsJson) {
  auto h = Historian::open(location());
  auto header = run_header_from_json(run_json_text("P-7/o", 2));
  header.run_id = "P-7/other";
  EXPECT_THROW(h.begin_run(header), InputError);
  EXPECT_THROW(run_header_from_json("{not json"), InputError);
  EXPECT_THROW(run_header_from_json(R"({"format": "ambdiag.run/1"})"), InputError);
}

}  // namespace
}  // namespace ambdiag::storage
