// A matrix of frequency response functions (FRFs) and the FRF file format
// (`ambdiag.frf/1`, ../shared/specs/frf-file.md).
#pragma once

#include <complex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ambdiag {

enum class FrfQuantity { compliance, mobility, accelerance };
std::string to_string(FrfQuantity q);

// One FRF H = output / input over the frequency grid of its FrfData.
struct FrfEntry {
  std::string output;  // sensor name
  std::string input;   // actuator name
  std::vector<std::complex<double>> h;
  std::vector<double> sigma;  // std of the complex estimate per line; empty if absent
  std::vector<double> coh;    // ordinary coherence per line; empty if absent
};

struct FrfData {
  // Metadata in file order, except the format line; keys `pump_id`,
  // `run_id`, `speed_rpm`, `quantity`, `unit` are mirrored in the fields
  // below when read. Unknown keys are kept.
  std::vector<std::pair<std::string, std::string>> metadata;
  std::optional<double> speed_rpm;
  FrfQuantity quantity = FrfQuantity::compliance;
  std::string unit = "m/N";  // um/N and mm/N are converted to m/N on read

  std::vector<double> freq_hz;  // strictly increasing, > 0
  std::vector<FrfEntry> entries;

  const FrfEntry* find(const std::string& output, const std::string& input) const;
  FrfEntry* find(const std::string& output, const std::string& input);
  // Distinct output and input names, in order of first appearance.
  std::vector<std::string> outputs() const;
  std::vector<std::string> inputs() const;
  std::optional<std::string> meta(const std::string& key) const;
  void set_meta(const std::string& key, const std::string& value);
  // Throws InputError if sizes disagree, values are not finite, frequencies
  // are not strictly increasing and positive, or an entry repeats.
  void validate() const;
};

// Reads an FRF file; throws InputError naming the line and column.
FrfData read_frf_csv(const std::string& path);
FrfData parse_frf_csv(const std::string& text, const std::string& source = "<text>");
// Writes with 17 significant digits (lossless for double); atomic (temp + rename).
void write_frf_csv(const std::string& path, const FrfData& frf);
std::string format_frf_csv(const FrfData& frf);

}  // namespace ambdiag
