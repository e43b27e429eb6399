// Fuzz entry point for the UFF58/58b reader: any input is either parsed or
// refused with InputError; anything else (crash, other exception, sanitizer
// report) is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ambdiag/core/error.h"
#include "ambdiag/core/uff58.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto records =
        ambdiag::parse_uff58(std::string(reinterpret_cast<const char*>(data), size), "<fuzz>");
    // Whatever was read must be writable and read back the same way.
    for (const bool binary : {false, true}) {
      try {
        (void)ambdiag::parse_uff58(ambdiag::format_uff58(records, binary), "<fuzz round trip>");
      } catch (const ambdiag::InputError&) {
        // Fields the writer cannot hold (e.g. a 6-digit function type) are refused, not a crash.
      }
    }
  } catch (const ambdiag::InputError&) {
  }
  return 0;
}
