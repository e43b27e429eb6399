// Run recordings (core/run_recording.h) in and out of the historian.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "ambdiag/storage/historian.h"

namespace ambdiag::storage {

struct ImportResult {
  std::string run_id;
  EndResult end;
  std::int64_t chunks = 0;
  std::int64_t duplicates = 0;  // chunks already held (importing twice stores nothing twice)
};

// Reads and checks a recording folder (run.json verbatim, samples.f32), then
// stores it as one run in chunks of about `chunk_bytes` (whole frames), in
// transactions of `chunks_per_transaction`, and ends it with the frame count
// and checksum of samples.f32. Throws InputError for a bad folder.
ImportResult import_recording(Historian& h, const std::string& run_dir, std::size_t chunk_bytes = 32768,
                              std::size_t chunks_per_transaction = 256);

// Writes the run as a recording folder: run.json as received, samples.f32 as
// the chunks held. Atomic: built in a temporary sibling folder and renamed
// into place; `out_dir` must not exist (or be an empty folder). Refuses a run
// that is not complete unless `allow_incomplete`.
void export_recording(Historian& h, const std::string& run_id, const std::string& out_dir,
                      bool allow_incomplete = false);

}  // namespace ambdiag::storage
