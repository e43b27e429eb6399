// Fuzz target for run.json (the metadata of a run recording). Text that is
// not JSON is the JSON library's refusal; an InputError is ours; anything
// else escaping, a crash or a sanitizer report is a bug. Metadata that is
// accepted must also write and read back unchanged.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/run_recording.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  ambdiag::RunRecording run;
  try {
    run = ambdiag::run_from_json(doc);
  } catch (const ambdiag::InputError&) {
    return 0;
  }
  // Not caught: what was read must be written and read again.
  const nlohmann::json written = ambdiag::run_to_json(run);
  if (ambdiag::run_to_json(ambdiag::run_from_json(written)) != written) __builtin_trap();
  return 0;
}
