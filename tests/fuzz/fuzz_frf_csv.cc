// Fuzz target for the FRF file reader. An InputError is the expected refusal;
// any other exception, a crash or a sanitizer report is a bug. A file that is
// accepted must also write and read back to the same values.
#include <cstddef>
#include <cstdint>
#include <string>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"

namespace {

bool same(const ambdiag::FrfData& a, const ambdiag::FrfData& b) {
  if (a.freq_hz != b.freq_hz || a.entries.size() != b.entries.size()) return false;
  if (a.quantity != b.quantity || a.unit != b.unit || a.speed_rpm != b.speed_rpm) return false;
  for (size_t i = 0; i < a.entries.size(); ++i) {
    const auto& x = a.entries[i];
    const auto& y = b.entries[i];
    if (x.output != y.output || x.input != y.input || x.h != y.h || x.sigma != y.sigma || x.coh != y.coh) {
      return false;
    }
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  ambdiag::FrfData frf;
  try {
    frf = ambdiag::parse_frf_csv(text, "fuzz.csv");
  } catch (const ambdiag::InputError&) {
    return 0;
  }
  // Not caught: the writer must accept whatever the reader accepted.
  const ambdiag::FrfData back = ambdiag::parse_frf_csv(ambdiag::format_frf_csv(frf), "round-trip.csv");
  if (!same(frf, back)) __builtin_trap();
  return 0;
}
