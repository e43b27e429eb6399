// A recording imported into the historian comes back bit-identical.
#include "ambdiag/storage/recording_io.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

namespace fs = std::filesystem;

const fs::path kRefRun = "reference_pump/run_ref_1";

TEST(RecordingIo, ImportedReferenceRunReadsBackBitIdentical) {
  const fs::path dir = ambdiag::testing::data_file(kRefRun.string());
  const std::string samples = read_file_bytes((dir / "samples.f32").string());
  const std::string run_json = read_file_bytes((dir / "run.json").string());
  auto h = Historian::open((ambdiag::testing::scratch_dir() / "h.db").string());
  const auto res = import_recording(h, dir.string());
  EXPECT_EQ(res.end.status, RunStatus::complete) << res.end.reason;
  EXPECT_EQ(res.duplicates, 0);
  const auto info = h.find_run(res.run_id);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->pump_id, "P-101");
  EXPECT_EQ(info->header_json, run_json);
  EXPECT_EQ(info->samples_bytes(), static_cast<std::int64_t>(samples.size()));
  // Chunks of whole frames, at most 32 KiB each.
  const std::int64_t frames_per_chunk = 32768 / (4 * info->n_channels);
  EXPECT_EQ(info->received_chunks, (info->received_frames + frames_per_chunk - 1) / frames_per_chunk);
  EXPECT_EQ(h.read_samples(res.run_id), samples);

  // Importing again stores nothing twice.
  const auto again = import_recording(h, dir.string());
  EXPECT_EQ(again.duplicates, again.chunks);
  EXPECT_EQ(again.end.status, RunStatus::complete);
  EXPECT_EQ(h.find_run(res.run_id)->received_chunks, info->received_chunks);
}

TEST(RecordingIo, ExportWritesTheRecordingFolderBitIdentical) {
  const fs::path dir = ambdiag::testing::data_file(kRefRun.string());
  const fs::path scratch = ambdiag::testing::scratch_dir();
  auto h = Historian::open((scratch / "h.db").string());
  const auto res = import_recording(h, dir.string(), 10000, 7);  // odd sizes: chunking must not matter
  ASSERT_EQ(res.end.status, RunStatus::complete);
  const fs::path out = scratch / "out" / "run";
  fs::create_directories(out.parent_path());
  export_recording(h, res.run_id, out.string());
  for (const char* f : {"run.json", "samples.f32"})
    EXPECT_EQ(read_file_bytes((out / f).string()), read_file_bytes((dir / f).string())) << f;
  EXPECT_EQ(std::distance(fs::directory_iterator(out.parent_path()), fs::directory_iterator()), 1);  // no temp left
  // A non-empty target is never overwritten.
  EXPECT_THROW(export_recording(h, res.run_id, out.string()), InputError);
  EXPECT_THROW(export_recording(h, "no/such:run", (scratch / "x").string()), InputError);
}

TEST(RecordingIo, ExportRefusesAnIncompleteRunUnlessAsked) {
  const fs::path scratch = ambdiag::testing::scratch_dir();
  auto h = Historian::open((scratch / "h.db").string());
  const fs::path dir = ambdiag::testing::data_file(kRefRun.string());
  const auto header = run_header_from_json(read_file_bytes((dir / "run.json").string()));
  h.begin_run(header);
  h.mark_incomplete(header.run_id, "agent gone");
  EXPECT_THROW(export_recording(h, header.run_id, (scratch / "a").string()), InputError);
  EXPECT_FALSE(fs::exists(scratch / "a"));
  export_recording(h, header.run_id, (scratch / "b").string(), true);
  EXPECT_EQ(fs::file_size(scratch / "b" / "samples.f32"), 0u);
}

TEST(RecordingIo, ImportRefusesABadFolderAndStoresNothing) {
  const fs::path scratch = ambdiag::testing::scratch_dir();
  auto h = Historian::open((scratch / "h.db").string());
  fs::create_directories(scratch / "bad");
  write_file_atomic((scratch / "bad" / "run.json").string(), "{}");
  write_file_atomic((scratch / "bad" / "samples.f32").string(), "abc");
  EXPECT_THROW(import_recording(h, (scratch / "bad").string()), InputError);
  EXPECT_THROW(import_recording(h, (scratch / "missing").string()), InputError);
  EXPECT_EQ(h.count_runs(), 0);
}

}  // namespace
}  // namespace ambdiag::storage
