// Crash safety: a writer killed in the middle of a put_chunks transaction
// leaves a database that opens consistent, with none of the half batch.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>

#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "crash_child.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::as_string;
using ambdiag::testing::checksum_of;
using ambdiag::testing::cut_chunks;

TEST(HistorianCrash, KilledInTheMiddleOfABatchLeavesNoHalfBatch) {
  const std::string path = (ambdiag::testing::scratch_dir() / "h.db").string();
  constexpr int kChannels = 8;
  constexpr std::int64_t kFramesPerChunk = 1024;  // 32 KiB chunks
  const auto header = run_header_from_json(ambdiag::testing::run_json_text("P-7/crash", kChannels));
  const auto bytes = ambdiag::testing::samples_bytes(kFramesPerChunk * 400, kChannels, 21);
  const auto chunks = cut_chunks(bytes, kChannels, kFramesPerChunk);
  constexpr size_t kCommitted = 100;  // the first batch commits; the second (300 chunks) is cut short

  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(fds[0]);
    auto h = Historian::open(path);
    h.begin_run(header);
    h.put_chunks(header.run_id, std::span(chunks).subspan(0, kCommitted));
    // The second batch: its 250th chunk reads from a page that faults, after
    // 249 chunks (8 MB) went into the open transaction.
    const long page = ::sysconf(_SC_PAGESIZE);
    void* guard = ::mmap(nullptr, static_cast<size_t>(page) * 8, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    std::vector<Chunk> batch(chunks.begin() + kCommitted, chunks.end());
    batch[249].bytes = {static_cast<const std::uint8_t*>(guard), batch[249].bytes.size()};
    crash::report_guard_page_faults(fds[1]);
    h.put_chunks(header.run_id, batch);
    ::_exit(3);  // not reached: the guard page faults first
  }
  ::close(fds[1]);
  const crash::Killed k = crash::kill_after_report(child, fds[0]);
  ASSERT_TRUE(k.reported) << "the child ended before it got into the batch";
  EXPECT_EQ(k.byte, 'T');
  ASSERT_TRUE(k.by_sigkill());

  // Opens (recovering the WAL), consistent, with exactly the first batch.
  auto h = Historian::open(path);
  EXPECT_EQ(raw_integrity_check(path), "ok");
  const auto info = h.find_run(header.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->received_chunks, static_cast<std::int64_t>(kCommitted));
  const auto first = std::span(bytes).subspan(0, kCommitted * kFramesPerChunk * kChannels * 4);
  EXPECT_EQ(h.read_samples(header.run_id), as_string(first));
  // The agent resends; the run completes as if nothing happened.
  h.put_chunks(header.run_id, chunks);
  const auto end = h.end_run(header.run_id, static_cast<std::int64_t>(chunks.size()) * kFramesPerChunk,
                             checksum_of(bytes));
  EXPECT_EQ(end.status, RunStatus::complete) << end.reason;
}

}  // namespace
}  // namespace ambdiag::storage
