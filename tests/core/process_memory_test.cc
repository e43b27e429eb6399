// retain_freed_memory(): a block of a few MB freed by the process stays in
// its heap for the next allocation instead of going back to the kernel.
#include "ambdiag/core/process_memory.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>

namespace {

// Free bytes the allocator holds in the main arena (not returned to the kernel).
size_t free_heap_bytes() { return mallinfo2().fordblks; }

// Allocates, touches and frees `bytes`; returns how much more free heap the
// allocator holds afterwards.
size_t retained_after_free(size_t bytes) {
  const size_t before = free_heap_bytes();
  char* p = static_cast<char*>(std::malloc(bytes));
  if (!p) return 0;
  std::memset(p, 1, bytes);
  std::free(p);
  const size_t after = free_heap_bytes();
  return after > before ? after - before : 0;
}

// AddressSanitizer replaces malloc: glibc's statistics say nothing then.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kGlibcMalloc = false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kGlibcMalloc = false;
#else
constexpr bool kGlibcMalloc = true;
#endif
#else
constexpr bool kGlibcMalloc = true;
#endif

TEST(ProcessMemory, FreedBlocksOfSeveralMegabytesStayWithTheProcess) {
  if (!kGlibcMalloc) GTEST_SKIP() << "malloc is not glibc's (sanitizer build)";
  ambdiag::retain_freed_memory();
  // Below the mmap threshold and within the trim threshold: kept whole
  // (with glibc's defaults a 4 MiB block is mapped and unmapped on free).
  for (const size_t mib : {4, 12}) {
    retained_after_free(mib << 20);
    EXPECT_GE(free_heap_bytes(), mib << 20) << mib << " MiB";
  }
}

TEST(ProcessMemory, BlocksAboveTheMmapThresholdGoBackToTheKernel) {
  if (!kGlibcMalloc) GTEST_SKIP() << "malloc is not glibc's (sanitizer build)";
  ambdiag::retain_freed_memory();
  // What the process keeps is bounded: a block above 16 MiB is mapped and
  // returned whole on free.
  EXPECT_LT(retained_after_free(std::size_t{24} << 20), std::size_t{24} << 20);
}

}  // namespace
#endif
