// Fuzz target: the plant model reader. Only InputError may escape the parser;
// anything else (a crash, a sanitizer report, another exception) is a bug.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/plant_model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  try {
    const ambdiag::PlantModel p = ambdiag::plant_from_json(doc);
    // A model that was accepted must survive its own round trip.
    (void)ambdiag::plant_from_json(ambdiag::plant_to_json(p));
  } catch (const ambdiag::InputError&) {
  }
  return 0;
}
