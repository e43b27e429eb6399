// Background checkpoints (Historian::checkpoint_in_background) on a real
// SQLite file: the log is copied into the database by the checkpoint thread,
// stays bounded, and nothing committed is lost or changed.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>

#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::as_string;
using ambdiag::testing::checksum_of;
using ambdiag::testing::cut_chunks;
using ambdiag::testing::run_json_text;
using ambdiag::testing::samples_bytes;

namespace fs = std::filesystem;

// 8 channels x 512 frames = 16 KiB chunks; 40 batches of 16 chunks = 10 MiB,
// about 2600 log pages of 4 KiB.
constexpr int kChannels = 8, kFrames = 512, kPerBatch = 16, kBatches = 40;

TEST(Checkpoint, TheThreadCopiesTheLogAndKeepsItBoundedWithoutLosingACommit) {
  const auto path = (ambdiag::testing::scratch_dir() / "ck.db").string();
  const auto bytes = samples_bytes(int64_t{kFrames} * kPerBatch * kBatches, kChannels, 7);
  const auto chunks = cut_chunks(bytes, kChannels, kFrames);
  constexpr int kTrigger = 200;  // pages
  uintmax_t wal_peak = 0;
  {
    auto h = Historian::open(path);
    h.checkpoint_in_background(kTrigger);
    EXPECT_THROW(h.checkpoint_in_background(kTrigger), std::logic_error);
    h.begin_run(run_header_from_json(run_json_text("P-7/ck", kChannels)));
    for (int b = 0; b < kBatches; ++b) {
      h.put_chunks("P-7/ck", std::span(chunks).subspan(static_cast<size_t>(b) * kPerBatch, kPerBatch));
      std::error_code ec;
      wal_peak = std::max(wal_peak, fs::file_size(path + "-wal", ec));
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // lets the thread run, as the server's commits do
    }
    const auto st = h.checkpoint_stats();
    // Every batch writes about 65 pages, so about 13 triggers; the thread
    // did (nearly) all of them, and copied what the log held.
    EXPECT_GE(st.background, 3) << "checkpoints by the thread";
    EXPECT_GT(st.pages_copied, 4 * kTrigger);
    EXPECT_EQ(st.errors, 0) << st.last_error;
    EXPECT_EQ(h.end_run("P-7/ck", int64_t{kFrames} * kPerBatch * kBatches, checksum_of(bytes)).status,
              RunStatus::complete);
  }
  // The log is reused from its start once copied: bounded by the inline
  // limit (16 x trigger pages plus one batch), far below the 10 MiB written.
  EXPECT_LT(wal_peak, (16u * kTrigger + 200u) * 4200u);
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(r.read_samples("P-7/ck"), as_string(bytes));
  EXPECT_EQ(r.checkpoint_stats().background, 0);  // never started on this one
}

TEST(Checkpoint, IsRefusedOnAReader) {
  const auto path = (ambdiag::testing::scratch_dir() / "ck2.db").string();
  { auto h = Historian::open(path); }
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_THROW(r.checkpoint_in_background(), std::logic_error);
}

// The time trigger: a commit far below the size trigger is durable within
// about durable_within, and the listener hears of it.
TEST(Checkpoint, ACommitBelowTheSizeTriggerIsDurableWithinTheTimeTrigger) {
  const auto path = (ambdiag::testing::scratch_dir() / "ck3.db").string();
  auto h = Historian::open(path);
  CheckpointOptions opt;
  opt.durable_within = std::chrono::milliseconds(100);
  h.checkpoint_in_background(opt);
  std::atomic<uint64_t> heard{0};
  h.on_durable([&](uint64_t g) { heard = g; });
  h.begin_run(run_header_from_json(run_json_text("P-7/time", kChannels)));
  const auto bytes = samples_bytes(kFrames, kChannels, 9);
  const auto t0 = std::chrono::steady_clock::now();
  h.put_chunks("P-7/time", cut_chunks(bytes, kChannels, kFrames));  // 5 pages: the size trigger never fires
  const uint64_t gen = h.commit_generation();
  EXPECT_GE(gen, 3u);  // the state at open, the header, the chunk
  EXPECT_LT(h.durable_generation(), gen);
  while (h.durable_generation() < gen && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(h.durable_generation(), gen);
  EXPECT_GT(waited_s, 0.05);  // not before its time: no checkpoint per commit
  EXPECT_LT(waited_s, 1.0);
  EXPECT_EQ(heard.load(), h.durable_generation());
  EXPECT_GE(h.checkpoint_stats().time_triggered, 1);
  h.on_durable(nullptr);
}

// synchronous = FULL: durable when the commit returns.
TEST(Checkpoint, WithSyncCommitsACommitIsDurableWhenItReturns) {
  const auto path = (ambdiag::testing::scratch_dir() / "ck4.db").string();
  auto h = Historian::open(path);
  CheckpointOptions opt;
  opt.sync_commits = true;
  opt.durable_within = std::chrono::seconds(60);  // the time trigger plays no part
  h.checkpoint_in_background(opt);
  h.begin_run(run_header_from_json(run_json_text("P-7/full", kChannels)));
  EXPECT_EQ(h.durable_generation(), h.commit_generation());
  EXPECT_THROW(Historian::open(path, Historian::Mode::read).commit_generation(), std::logic_error);
}

}  // namespace
}  // namespace ambdiag::storage
