#include "ambdiag/core/process_memory.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace ambdiag {

void retain_freed_memory() {
#if defined(__GLIBC__)
  // Setting either turns off glibc's dynamic threshold, which would raise
  // them only after a mapped block has been freed once, and not past the
  // sizes it has seen.
  mallopt(M_MMAP_THRESHOLD, static_cast<int>(kMmapThresholdBytes));
  mallopt(M_TRIM_THRESHOLD, static_cast<int>(kTrimThresholdBytes));
#endif
}

}  // namespace ambdiag
