// Durability under a simulated power cut (storage/power_cut.h): a child
// process commits chunks one transaction each and reports which commits the
// historian called durable; the power-cut VFS then drops everything not
// fsynced and ends the child. Every chunk committed at or before the last
// durable commit must be in the file afterwards, byte for byte, and the file
// must pass integrity_check. Cut points are random (seeded).
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <random>
#include <sstream>
#include <string>
#include <thread>

#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/power_cut.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using namespace std::chrono_literals;
using ambdiag::testing::cut_chunks;

constexpr int kChannels = 8;
constexpr std::int64_t kFramesPerChunk = 128;  // 4 KiB chunks, one transaction each
constexpr int kChunks = 200;

struct Outcome {
  int exit_code = -1;
  std::vector<std::uint64_t> gen_of_chunk;  // the commit that stored chunk i (0: not committed)
  std::uint64_t durable = 0;                // the highest commit reported durable
  std::uint64_t writes = 0, syncs = 0;      // reported at the end of an uncut run
};

void say(int fd, const std::string& line) {
  const std::string l = line + "\n";
  if (::write(fd, l.data(), l.size()) != static_cast<ssize_t>(l.size())) ::_exit(5);
}

// The child: opens `path` through the VFS with `plan`, commits the chunks,
// reports "C seq gen" after each commit and "D gen" for each durable one.
Outcome run_child(const std::string& path, const power_cut::Plan& plan, const CheckpointOptions& opt,
                  const RunHeader& header, const std::vector<Chunk>& chunks) {
  int fds[2];
  EXPECT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(fds[0]);
    power_cut::install(plan);
    {
      auto h = Historian::open(path);
      h.checkpoint_in_background(opt);
      const int out = fds[1];
      h.on_durable([out](std::uint64_t g) { say(out, "D " + std::to_string(g)); });
      h.begin_run(header);
      for (const auto& c : chunks) {
        h.put_chunks(header.run_id, std::span(&c, 1));
        say(out, "C " + std::to_string(c.seq) + " " + std::to_string(h.commit_generation()));
        std::this_thread::sleep_for(200us);  // the time trigger gets its turns
      }
    }
    say(fds[1], "W " + std::to_string(power_cut::writes_seen()) + " " + std::to_string(power_cut::syncs_seen()));
    ::_exit(0);
  }
  ::close(fds[1]);
  Outcome o;
  o.gen_of_chunk.assign(chunks.size(), 0);
  std::string text;
  char buf[4096];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) text.append(buf, static_cast<size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::istringstream in(text);
  for (std::string kind; in >> kind;) {
    std::uint64_t a = 0, b = 0;
    if (kind == "C") {
      in >> a >> b;
      o.gen_of_chunk.at(a) = b;
    } else if (kind == "D") {
      in >> a;
      o.durable = std::max(o.durable, a);
    } else {
      in >> o.writes >> o.syncs;
    }
  }
  return o;
}

// The chunk's bytes as the file holds them, or empty.
std::string stored_chunk(const std::string& path, const std::string& run_id, std::int64_t seq) {
  sqlite3* db = nullptr;
  sqlite3_open(path.c_str(), &db);
  sqlite3_stmt* s = nullptr;
  sqlite3_prepare_v2(db, "SELECT data FROM sample_chunks WHERE run_id = ? AND seq = ?", -1, &s, nullptr);
  sqlite3_bind_text(s, 1, run_id.c_str(), -1, SQLITE_TRANSIENT);
  sqlite3_bind_int64(s, 2, seq);
  std::string out;
  if (sqlite3_step(s) == SQLITE_ROW)
    out.assign(static_cast<const char*>(sqlite3_column_blob(s, 0)), static_cast<size_t>(sqlite3_column_bytes(s, 0)));
  sqlite3_finalize(s);
  sqlite3_close(db);
  return out;
}

struct Tally {
  int cuts = 0;
  std::int64_t durable_chunks = 0, lost_durable = 0, lost_not_durable = 0;
};

// Cuts at `points` random writes (or fsyncs) of a run, each on a fresh file.
Tally cut_at_random_points(const CheckpointOptions& opt, power_cut::Plan::Count count, int points, unsigned seed,
                           bool random_subset) {
  const auto header = run_header_from_json(ambdiag::testing::run_json_text("P-7/cut", kChannels));
  const auto bytes = ambdiag::testing::samples_bytes(kFramesPerChunk * kChunks, kChannels, seed);
  const auto chunks = cut_chunks(bytes, kChannels, kFramesPerChunk);
  const auto dir = ambdiag::testing::scratch_dir();
  // How many writes and fsyncs an uncut run makes: where the cuts may fall.
  const Outcome base = run_child((dir / "base.db").string(), {}, opt, header, chunks);
  EXPECT_EQ(base.exit_code, 0);
  EXPECT_GT(base.writes, 0u);
  EXPECT_GT(base.syncs, 0u);
  std::mt19937_64 rng(seed);
  Tally t;
  for (int i = 0; i < points; ++i) {
    const std::string path = (dir / ("cut-" + std::to_string(i) + ".db")).string();
    power_cut::Plan plan;
    plan.count = count;
    plan.at = 1 + rng() % (count == power_cut::Plan::Count::writes ? base.writes : base.syncs);
    if (random_subset) plan.seed = rng();
    const Outcome o = run_child(path, plan, opt, header, chunks);
    if (o.exit_code != power_cut::kExitCode) continue;  // ended before the cut point
    ++t.cuts;
    EXPECT_EQ(raw_integrity_check(path), "ok") << "cut " << i;
    EXPECT_NO_THROW(Historian::open(path)) << "cut " << i;  // a restart: migrates a file cut before its schema was durable
    for (size_t k = 0; k < chunks.size(); ++k) {
      if (o.gen_of_chunk[k] == 0) continue;  // never committed
      const bool durable = o.gen_of_chunk[k] <= o.durable;
      const std::string held = stored_chunk(path, header.run_id, chunks[k].seq);
      const bool ok = held == ambdiag::testing::as_string(chunks[k].bytes);
      EXPECT_TRUE(ok || held.empty()) << "chunk " << k << " stored with other bytes";
      if (durable) {
        ++t.durable_chunks;
        t.lost_durable += ok ? 0 : 1;
      } else {
        t.lost_not_durable += ok ? 0 : 1;
      }
    }
  }
  return t;
}

// Prints the tally and checks what every case must show: enough cuts
// reached, chunks called durable before them, none of those lost.
void expect_no_durable_loss(const char* what, const Tally& t, int min_cuts) {
  std::printf("%s: %d cuts, %lld chunks acknowledged durable, %lld of them lost, %lld committed-only chunks lost\n",
              what, t.cuts, static_cast<long long>(t.durable_chunks), static_cast<long long>(t.lost_durable),
              static_cast<long long>(t.lost_not_durable));
  EXPECT_GE(t.cuts, min_cuts) << what;
  EXPECT_GT(t.durable_chunks, 0) << what;
  EXPECT_EQ(t.lost_durable, 0) << what;
}

// Size-triggered checkpoints during the run, and time-triggered ones.
CheckpointOptions frequent_checkpoints() {
  CheckpointOptions opt;
  opt.trigger_pages = 256;
  opt.inline_pages = 4096;
  opt.durable_within = 50ms;
  return opt;
}

TEST(PowerCut, CommitsCalledDurableByTheCheckpointsSurviveACut) {
  const CheckpointOptions opt = frequent_checkpoints();
  const Tally t = cut_at_random_points(opt, power_cut::Plan::Count::writes, 6, 21, false);
  expect_no_durable_loss("checkpoints", t, 4);
  // Whether some cut also takes commits not yet durable depends on where
  // the checkpoint thread stands at the cut (timing): the test below shows
  // deterministically that the simulation bites.
}

// The control: with no checkpoint at all (none triggered by size or time),
// nothing after the schema is synced, so a cut takes every commit made:
// the simulation drops what was written but not synced.
TEST(PowerCut, WithoutACheckpointACutTakesTheCommitsNotSynced) {
  CheckpointOptions opt;
  opt.trigger_pages = 1 << 30;
  opt.inline_pages = 1 << 30;
  opt.durable_within = std::chrono::hours(1);
  const Tally t = cut_at_random_points(opt, power_cut::Plan::Count::writes, 3, 57, false);
  std::printf("no checkpoints: %d cuts, %lld chunks acknowledged durable, %lld committed-only chunks lost\n", t.cuts,
              static_cast<long long>(t.durable_chunks), static_cast<long long>(t.lost_not_durable));
  EXPECT_GE(t.cuts, 2);
  EXPECT_EQ(t.durable_chunks, 0);  // nothing was called durable
  EXPECT_GT(t.lost_not_durable, 0);
}

TEST(PowerCut, DurableCommitsSurviveWhenARandomHalfOfTheUnsyncedWritesReachedTheDisk) {
  const CheckpointOptions opt = frequent_checkpoints();
  const Tally t = cut_at_random_points(opt, power_cut::Plan::Count::writes, 6, 33, true);
  expect_no_durable_loss("checkpoints, random subset", t, 4);
}

TEST(PowerCut, WithSynchronousFullEveryCommitIsDurableAtOnce) {
  CheckpointOptions opt;
  opt.sync_commits = true;
  const Tally t = cut_at_random_points(opt, power_cut::Plan::Count::syncs, 4, 45, false);
  expect_no_durable_loss("synchronous=FULL", t, 3);
  EXPECT_EQ(t.lost_not_durable, 0);  // none was committed without being durable
}

TEST(PowerCut, ABadPlanIsRefused) {
  power_cut::Plan p;
  p.count = power_cut::Plan::Count::writes;
  EXPECT_THROW(power_cut::install(p), std::invalid_argument);
}

}  // namespace
}  // namespace ambdiag::storage
