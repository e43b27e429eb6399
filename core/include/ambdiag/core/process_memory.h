// How an ambdiag process keeps the memory it frees.
//
// The numerical jobs allocate and free the same 0.1-10 MB matrices over and
// over (an FRF synthesis per parameter trial in explain and diagnosis, the
// Gram and Jacobian blocks of every LM step, the server's batches). With
// glibc's defaults a freed block above the mmap threshold goes back to the
// kernel at once and a free heap top above the trim threshold is cut off,
// so each repetition faults the same pages in again: perf put 23 % of the
// reference pump's FRF synthesis in the kernel's page-fault handler
// (docs/benchmarks.md, "Plant model"). Every ambdiag executable calls this
// first thing in main().
#pragma once

#include <cstddef>

namespace ambdiag {

// Blocks up to 16 MiB come from the heap, and up to 32 MiB of free heap
// top stays with the process for reuse (glibc mallopt M_MMAP_THRESHOLD,
// M_TRIM_THRESHOLD; a no-op with other C libraries). Bounded: glibc keeps
// at most 8 arenas per core, so a server holds at most 32 MiB of freed
// memory per arena. Call before any threads start.
void retain_freed_memory();

inline constexpr std::size_t kMmapThresholdBytes = std::size_t{16} << 20;
inline constexpr std::size_t kTrimThresholdBytes = std::size_t{32} << 20;

}  // namespace ambdiag
