#include "ambdiag/core/frf_data.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "ambdiag/core/error.h"

namespace ambdiag {

std::string to_string(FrfQuantity q) {
  switch (q) {
    case FrfQuantity::compliance:
      return "compliance";
    case FrfQuantity::mobility:
      return "mobility";
    case FrfQuantity::accelerance:
      return "accelerance";
  }
  return "unknown";
}

const FrfEntry* FrfData::find(const std::string& output, const std::string& input) const {
  for (const auto& e : entries) {
    if (e.output == output && e.input == input) return &e;
  }
  return nullptr;
}

FrfEntry* FrfData::find(const std::string& output, const std::string& input) {
  return const_cast<FrfEntry*>(std::as_const(*this).find(output, input));
}

std::vector<std::string> FrfData::outputs() const {
  std::vector<std::string> names;
  for (const auto& e : entries) {
    if (std::find(names.begin(), names.end(), e.output) == names.end()) names.push_back(e.output);
  }
  return names;
}

std::vector<std::string> FrfData::inputs() const {
  std::vector<std::string> names;
  for (const auto& e : entries) {
    if (std::find(names.begin(), names.end(), e.input) == names.end()) names.push_back(e.input);
  }
  return names;
}

std::optional<std::string> FrfData::meta(const std::string& key) const {
  for (const auto& [k, v] : metadata) {
    if (k == key) return v;
  }
  return std::nullopt;
}

void FrfData::set_meta(const std::string& key, const std::string& value) {
  for (auto& [k, v] : metadata) {
    if (k == key) {
      v = value;
      return;
    }
  }
  metadata.emplace_back(key, value);
}

void FrfData::validate() const {
  const size_t n = freq_hz.size();
  if (n == 0) throw InputError("freq_hz: no frequency lines");
  for (size_t k = 0; k < n; ++k) {
    const double f = freq_hz[k];
    if (!std::isfinite(f)) throw InputError("freq_hz[" + std::to_string(k) + "]: not finite");
    if (!(f > 0.0)) throw InputError("freq_hz[" + std::to_string(k) + "]: must be > 0");
    if (k > 0 && !(f > freq_hz[k - 1])) {
      throw InputError("freq_hz[" + std::to_string(k) + "]: must be strictly increasing");
    }
  }
  if (entries.empty()) throw InputError("entries: no FRF entries");
  for (size_t i = 0; i < entries.size(); ++i) {
    const FrfEntry& e = entries[i];
    const std::string name = "entry H_" + e.output + "_" + e.input;
    if (e.output.empty() || e.input.empty()) throw InputError(name + ": empty output or input name");
    for (size_t j = 0; j < i; ++j) {
      if (entries[j].output == e.output && entries[j].input == e.input) throw InputError(name + ": repeated");
    }
    auto check_size = [&](size_t size, const char* what) {
      if (size != n) {
        throw InputError(name + ": " + what + " has " + std::to_string(size) + " values, freq_hz has " +
                         std::to_string(n));
      }
    };
    check_size(e.h.size(), "h");
    if (!e.sigma.empty()) check_size(e.sigma.size(), "sigma");
    if (!e.coh.empty()) check_size(e.coh.size(), "coh");
    const auto fail_at = [&](size_t k, const char* what) {
      throw InputError(name + ", freq_hz[" + std::to_string(k) + "]: " + what);
    };
    for (size_t k = 0; k < n; ++k) {
      if (!std::isfinite(e.h[k].real()) || !std::isfinite(e.h[k].imag())) fail_at(k, "h not finite");
      if (!e.sigma.empty() && !(e.sigma[k] >= 0.0 && std::isfinite(e.sigma[k]))) {
        fail_at(k, "sigma must be finite and >= 0");
      }
      if (!e.coh.empty() && !(e.coh[k] >= 0.0 && e.coh[k] <= 1.0)) fail_at(k, "coh must be in 0..1");
    }
  }
}

}  // namespace ambdiag
