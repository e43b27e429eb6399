// FRF matrix <-> UFF dataset 58 records, one complex-double FRF record
// (function type 4) per entry. The mapping is documented in docs/formats.md
// ("UFF58"); the round trip FrfData -> records -> FrfData is exact.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iterator>
#include <map>
#include <optional>
#include <string_view>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/uff58.h"

namespace ambdiag {
namespace {

using std::string_view;

constexpr string_view kNamesPrefix = "ambdiag: ";  // id4 = "ambdiag: <output> / <input>"
constexpr string_view kNamesSeparator = " / ";
constexpr string_view kId1Prefix = "FRF ";  // id1 = "FRF <quantity> (<unit>)"
constexpr int kFuncFrf = 4;
constexpr int kSpecUnknown = 0;
constexpr int kSpecForce = 13;
constexpr int kSpecFrequency = 18;
constexpr int kInputNodeOffset = 1000;  // outputs are nodes 1, 2, ...; inputs 1001, 1002, ...
constexpr size_t kIdWidth = 80;

struct QuantityInfo {
  FrfQuantity quantity;
  const char* name;
  int spec;  // UFF specific data type of the ordinate numerator
  const char* label;
  const char* units;  // SI, the numerator of the default unit <units>/N
};
constexpr QuantityInfo kQuantities[] = {
    {FrfQuantity::compliance, "compliance", 8, "Displacement", "m"},
    {FrfQuantity::mobility, "mobility", 11, "Velocity", "m/s"},
    {FrfQuantity::accelerance, "accelerance", 12, "Acceleration", "m/s^2"},
};

const QuantityInfo& info(FrfQuantity q) {
  for (const auto& i : kQuantities) {
    if (i.quantity == q) return i;
  }
  return kQuantities[0];
}

// Names of the UFF function types (record 6, field 1), for messages.
std::string func_type_name(int t) {
  static const char* kNames[] = {"general",
                                 "time response",
                                 "auto spectrum",
                                 "cross spectrum",
                                 "frequency response function",
                                 "transmissibility",
                                 "coherence",
                                 "auto correlation",
                                 "cross correlation",
                                 "power spectral density"};
  return t >= 0 && t < static_cast<int>(std::size(kNames)) ? kNames[t] : "other";
}

std::optional<std::string> meta(const FrfData& frf, string_view key) {
  for (const auto& [k, v] : frf.metadata) {
    if (k == key) return v;
  }
  return std::nullopt;
}

std::string shortest(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

// Direction code from the last letter of a sensor/actuator name (`xAx`,
// `fAy`, `fZ`): +X 1, +Y 2, +Z 3; 0 (scalar) when there is none.
int direction_from_name(const std::string& name) {
  const char c = static_cast<char>(std::tolower(static_cast<unsigned char>(name.back())));
  return c == 'x' ? 1 : c == 'y' ? 2 : c == 'z' ? 3 : 0;
}

// Name of a foreign DOF: [entity:]n<node>[+|-<axis>], e.g. `n12+X`.
std::string dof_name(const std::string& entity, int node, int dir) {
  std::string name;
  if (!entity.empty() && entity != "NONE") {
    for (const char c : entity) {
      const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                        c == '.' || c == '+' || c == '-';
      name += keep ? c : '-';
    }
    name += ':';
  }
  name += "n" + std::to_string(node);
  if (dir != 0) {
    static const char* kAxes[] = {"X", "Y", "Z", "RX", "RY", "RZ"};
    const int64_t a = std::abs(static_cast<int64_t>(dir));
    name += dir > 0 ? '+' : '-';
    name += a <= 6 ? std::string(kAxes[a - 1]) : "D" + std::to_string(a);
  }
  return name;
}

[[noreturn]] void fail_export(const std::string& what) { throw InputError("UFF58 export: " + what); }

void check_name(const std::string& name, const char* what) {
  if (name.empty()) fail_export(std::string("empty ") + what + " name");
  if (name.front() == ' ' || name.back() == ' ') {
    fail_export(std::string(what) + " name '" + name + "' has leading or trailing blanks");
  }
  for (const char c : name) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f)
      fail_export(std::string(what) + " name '" + name + "' contains a control character");
  }
}

std::string id_line(const std::string& key, const std::optional<std::string>& value) {
  if (!value) return "NONE";
  const std::string line = key + ": " + *value;
  if (line.size() > kIdWidth) fail_export(key + " '" + *value + "' does not fit an 80-character id line");
  return line;
}

// The value of a "key: value" id line written by frf_to_uff58, if it is one.
std::optional<std::string> id_value(const std::string& line, string_view key) {
  const std::string prefix = std::string(key) + ": ";
  if (line.compare(0, prefix.size(), prefix) != 0) return std::nullopt;
  return line.substr(prefix.size());
}

UffAxis axis(int spec, int length_exp, int force_exp, const std::string& label, const std::string& units) {
  UffAxis a;
  a.spec_data_type = spec;
  a.length_exp = length_exp;
  a.force_exp = force_exp;
  a.label = label;
  a.units = units;
  return a;
}

}  // namespace

std::vector<Uff58Record> frf_to_uff58(const FrfData& frf) {
  if (frf.entries.empty()) fail_export("no FRF entries");
  const std::vector<double>& f = frf.freq_hz;
  const size_t n = f.size();
  if (n == 0) fail_export("no frequency lines");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(f[i]) || !(f[i] > 0.0) || (i > 0 && !(f[i] > f[i - 1]))) {
      fail_export("freq_hz[" + std::to_string(i) + "] = " + shortest(f[i]) +
                  ": must be finite, > 0 and increasing");
    }
  }

  // Even spacing only when the reader's x_min + i * dx gives f back bit for bit.
  auto uniform_with = [&](double dx) {
    for (size_t i = 0; i < n; ++i) {
      if (f[0] + static_cast<double>(i) * dx != f[i]) return false;
    }
    return true;
  };
  double dx = 0.0;
  bool even = n == 1;
  if (n > 1) {
    for (const double candidate : {f[1] - f[0], (f[n - 1] - f[0]) / static_cast<double>(n - 1)}) {
      if (!even && candidate > 0.0 && uniform_with(candidate)) {
        even = true;
        dx = candidate;
      }
    }
  }

  const QuantityInfo& q = info(frf.quantity);
  // The numerator units label: the unit without its "/N" when it has one.
  std::string num_units = q.units;
  if (frf.unit.size() > 2 && frf.unit.size() <= 22 && frf.unit.ends_with("/N")) {
    num_units = frf.unit.substr(0, frf.unit.size() - 2);
  }
  const std::optional<std::string> speed =
      frf.speed_rpm ? std::optional<std::string>(shortest(*frf.speed_rpm)) : meta(frf, "speed_rpm");
  const std::string id1 = std::string(kId1Prefix) + q.name + " (" + frf.unit + ")";
  if (id1.size() > kIdWidth) fail_export("unit '" + frf.unit + "' does not fit an 80-character id line");
  const std::string id2 = id_line("pump_id", meta(frf, "pump_id"));
  const std::string id3 = id_line("run_id", meta(frf, "run_id"));
  const std::string id5 = id_line("speed_rpm", speed);

  std::map<std::string, int> output_node, input_node;
  std::map<std::pair<std::string, std::string>, size_t> seen;
  std::vector<Uff58Record> records;
  records.reserve(frf.entries.size());
  for (size_t k = 0; k < frf.entries.size(); ++k) {
    const FrfEntry& e = frf.entries[k];
    check_name(e.output, "output");
    check_name(e.input, "input");
    if (e.output.find(kNamesSeparator) != std::string::npos) {
      fail_export("output name '" + e.output + "' contains ' / '");
    }
    if (const auto [it, fresh] = seen.emplace(std::pair(e.output, e.input), k); !fresh) {
      fail_export("entries " + std::to_string(it->second) + " and " + std::to_string(k) + " are both " +
                  e.output + " / " + e.input);
    }
    if (e.h.size() != n) {
      fail_export("entry " + e.output + " / " + e.input + " has " + std::to_string(e.h.size()) +
                  " values for " + std::to_string(n) + " frequencies");
    }
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(e.h[i].real()) || !std::isfinite(e.h[i].imag())) {
        fail_export("entry " + e.output + " / " + e.input + " value " + std::to_string(i) + " is not finite");
      }
    }
    output_node.emplace(e.output, static_cast<int>(output_node.size()) + 1);
    input_node.emplace(e.input, kInputNodeOffset + static_cast<int>(input_node.size()) + 1);

    Uff58Record r;
    r.id1 = id1;
    r.id2 = id2;
    r.id3 = id3;
    r.id4 = std::string(kNamesPrefix) + e.output + std::string(kNamesSeparator) + e.input;
    if (r.id4.size() > kIdWidth) {
      fail_export("names " + e.output + " / " + e.input + " do not fit an 80-character id line");
    }
    r.id5 = id5;
    r.func_type = kFuncFrf;
    r.func_id = static_cast<int>(k) + 1;
    r.rsp_ent_name = e.output.substr(0, 10);
    r.rsp_node = output_node.at(e.output);
    r.rsp_dir = direction_from_name(e.output);
    r.ref_ent_name = e.input.substr(0, 10);
    r.ref_node = input_node.at(e.input);
    r.ref_dir = direction_from_name(e.input);
    r.ord_data_type = 6;
    r.even_spacing = even;
    r.x_min = f[0];
    r.dx = dx;
    r.abscissa = axis(kSpecFrequency, 0, 0, "Frequency", "Hz");
    r.ordinate_num = axis(q.spec, 1, 0, q.label, num_units);
    r.ordinate_den = axis(kSpecForce, 0, 1, "Force", "N");
    r.z_axis = axis(kSpecUnknown, 0, 0, "NONE", "NONE");
    r.x = f;
    r.y = e.h;
    records.push_back(std::move(r));
  }
  return records;
}

FrfData frf_from_uff58(const std::vector<Uff58Record>& records) {
  if (records.empty()) throw InputError("UFF58: no dataset 58 records to build an FRF matrix from");
  const Uff58Record& first = records[0];
  FrfData frf;
  std::optional<FrfQuantity> quantity;
  std::string unit;
  const Uff58Record* ours = nullptr;  // first record written by frf_to_uff58: carries the metadata
  std::map<std::pair<std::string, std::string>, size_t> seen;

  for (size_t k = 0; k < records.size(); ++k) {
    const Uff58Record& r = records[k];
    const std::string where = "UFF58 record " + std::to_string(k + 1);
    auto fail = [&](const std::string& what) { throw InputError(where + ": " + what); };

    if (r.func_type != kFuncFrf) {
      fail("function type " + std::to_string(r.func_type) + " (" + func_type_name(r.func_type) +
           ") is not a frequency response function (4)");
    }
    if (r.abscissa.spec_data_type != kSpecFrequency && r.abscissa.spec_data_type != kSpecUnknown) {
      fail("abscissa data type " + std::to_string(r.abscissa.spec_data_type) + " is not frequency (18)");
    }
    if (r.ordinate_den.spec_data_type != kSpecForce && r.ordinate_den.spec_data_type != kSpecUnknown) {
      fail("ordinate denominator data type " + std::to_string(r.ordinate_den.spec_data_type) +
           " is not force (13)");
    }
    const QuantityInfo* q = nullptr;
    for (const auto& i : kQuantities) {
      if (i.spec == r.ordinate_num.spec_data_type) q = &i;
    }
    if (!q) {
      fail("ordinate numerator data type " + std::to_string(r.ordinate_num.spec_data_type) +
           " is not displacement (8), velocity (11) or acceleration (12)");
    }
    if (quantity && *quantity != q->quantity) {
      fail(std::string("quantity ") + q->name + " differs from record 1's " + info(*quantity).name);
    }
    quantity = q->quantity;
    if (r.x.size() != r.y.size() || r.y.empty()) fail("abscissa and ordinate sizes differ");
    if (r.x.size() != first.x.size()) {
      fail(std::to_string(r.x.size()) + " frequency lines, record 1 has " + std::to_string(first.x.size()));
    }
    if (r.x != first.x) fail("abscissa differs from record 1's; an FRF matrix needs one frequency grid");

    // Names and unit: ours from the id lines, foreign ones from the DOFs and axis labels.
    std::string output, input, record_unit;
    const bool is_ours = r.id4.starts_with(kNamesPrefix) &&
                         r.id4.find(kNamesSeparator, kNamesPrefix.size()) != std::string::npos;
    if (is_ours) {
      const size_t sep = r.id4.find(kNamesSeparator, kNamesPrefix.size());
      output = r.id4.substr(kNamesPrefix.size(), sep - kNamesPrefix.size());
      input = r.id4.substr(sep + kNamesSeparator.size());
      const std::string id1_head = std::string(kId1Prefix) + q->name + " (";
      if (r.id1.starts_with(id1_head) && r.id1.ends_with(")") && r.id1.size() > id1_head.size() + 1) {
        record_unit = r.id1.substr(id1_head.size(), r.id1.size() - id1_head.size() - 1);
      }
      if (!ours) ours = &r;
    } else {
      output = dof_name(r.rsp_ent_name, r.rsp_node, r.rsp_dir);
      input = dof_name(r.ref_ent_name, r.ref_node, r.ref_dir);
    }
    if (output.empty() || input.empty()) fail("empty output or input name in id4 '" + r.id4 + "'");
    if (record_unit.empty()) {
      const std::string& nu = r.ordinate_num.units;
      const std::string& du = r.ordinate_den.units;
      record_unit = (nu.empty() || nu == "NONE" ? std::string(q->units) : nu) + "/" +
                    (du.empty() || du == "NONE" ? std::string("N") : du);
    }
    if (k == 0) unit = record_unit;
    if (record_unit != unit) fail("unit " + record_unit + " differs from record 1's " + unit);
    if (const auto [it, fresh] = seen.emplace(std::pair(output, input), k); !fresh) {
      fail("same output and input (" + output + " / " + input + ") as record " +
           std::to_string(it->second + 1));
    }

    FrfEntry e;
    e.output = std::move(output);
    e.input = std::move(input);
    e.h = r.y;
    frf.entries.push_back(std::move(e));
  }

  // The FRF matrix starts above 0 Hz; a 0 Hz (DC) line is dropped.
  const size_t skip = first.x[0] == 0.0 ? 1 : 0;
  frf.freq_hz.assign(first.x.begin() + static_cast<std::ptrdiff_t>(skip), first.x.end());
  if (frf.freq_hz.empty()) throw InputError("UFF58 record 1: no frequency line above 0 Hz");
  for (size_t i = 0; i < frf.freq_hz.size(); ++i) {
    const double fi = frf.freq_hz[i];
    if (!(fi > 0.0) || (i > 0 && !(fi > frf.freq_hz[i - 1]))) {
      throw InputError("UFF58 record 1: frequency " + shortest(fi) + " Hz at point " +
                       std::to_string(i + skip + 1) + " is not positive and increasing");
    }
  }
  for (auto& e : frf.entries) e.h.erase(e.h.begin(), e.h.begin() + static_cast<std::ptrdiff_t>(skip));

  frf.quantity = *quantity;
  frf.unit = unit;
  // Like the FRF file reader, foreign mm/N and um/N become m/N; records
  // written by frf_to_uff58 keep their unit so the round trip is exact.
  if (!ours) {
    const double scale = unit == "mm/N" ? 1e-3 : (unit == "um/N" || unit == "\u00b5m/N") ? 1e-6 : 1.0;
    if (scale != 1.0) {
      for (auto& e : frf.entries) {
        for (auto& h : e.h) h *= scale;
      }
      frf.unit = "m/N";
    }
  }
  if (ours) {
    if (auto v = id_value(ours->id2, "pump_id")) frf.metadata.emplace_back("pump_id", *v);
    if (auto v = id_value(ours->id3, "run_id")) frf.metadata.emplace_back("run_id", *v);
    if (auto v = id_value(ours->id5, "speed_rpm")) {
      double rpm = 0.0;
      const auto [end, ec] = std::from_chars(v->data(), v->data() + v->size(), rpm);
      if (ec != std::errc() || end != v->data() + v->size() || !std::isfinite(rpm)) {
        throw InputError("UFF58 record " + std::to_string(ours - records.data() + 1) + ": id5 speed_rpm '" +
                         *v + "' is not a number");
      }
      frf.speed_rpm = rpm;
      frf.metadata.emplace_back("speed_rpm", *v);
    }
  }
  frf.metadata.emplace_back("quantity", info(frf.quantity).name);
  frf.metadata.emplace_back("unit", frf.unit);
  return frf;
}

}  // namespace ambdiag
