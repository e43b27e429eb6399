// The FRF file (`ambdiag.frf/1`): reader and writer.
//
// Name splitting: a column `H_<output>_<input>_re` does not say where the
// output name ends, so sensor and actuator names in this file must not
// contain '_' (the sensor/actuator names of the plant spec, xAx or fAx, do
// not). The part between the prefix and the suffix must hold exactly one
// '_' with a non-empty name on each side; anything else is refused with the
// column named. The writer refuses such names rather than write a file it
// could not read back. (docs/formats.md, "FRF file".)
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"

namespace ambdiag {
namespace {

constexpr std::string_view kFormatLine = "ambdiag.frf/1";

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool is_blank(std::string_view s) { return s.find_first_not_of(" \t\r\n") == std::string_view::npos; }

// Cell text for an error message: quoted, cut short.
std::string quote(std::string_view cell) {
  constexpr size_t kMax = 40;
  std::string q = "'" + std::string(cell.substr(0, kMax));
  if (cell.size() > kMax) q += "...";
  return q + "'";
}

// Parses a whole cell as a finite double. Returns nullptr on success, else
// what is wrong. A leading '+' is accepted (other tools write it); values
// that overflow or underflow a double are refused rather than rounded to
// inf or 0.
const char* parse_double(std::string_view cell, double& value) {
  cell = trim(cell);
  if (cell.empty()) return "empty cell";
  const char* first = cell.data();
  const char* last = cell.data() + cell.size();
  if (*first == '+' && cell.size() > 1 && first[1] != '-' && first[1] != '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, last, value, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return "out of range for a double";
  if (ec != std::errc() || ptr != last) return "not a number";
  if (!std::isfinite(value)) return "NaN or infinity is refused";
  return nullptr;
}

// Splits `<output>_<input>`; both non-empty, exactly one '_'.
bool split_pair(std::string_view pair, std::string& output, std::string& input) {
  const size_t u = pair.find('_');
  if (u == std::string_view::npos || u == 0 || u + 1 == pair.size()) return false;
  if (pair.find('_', u + 1) != std::string_view::npos) return false;
  output = std::string(pair.substr(0, u));
  input = std::string(pair.substr(u + 1));
  return true;
}

void append_double(std::string& out, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 17);
  out.append(buf, r.ptr);
}

// Shortest text that reads back as the same double, for messages.
std::string shortest(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

enum class ColumnKind { freq, re, im, sigma, coh };

struct Column {
  std::string name;
  ColumnKind kind = ColumnKind::freq;
  size_t entry = 0;
};

class FrfCsvParser {
 public:
  FrfCsvParser(std::string_view text, const std::string& source) : rest_(text), source_(source) {}

  FrfData parse() {
    FrfData frf;
    if (rest_.substr(0, 3) == "\xEF\xBB\xBF") rest_.remove_prefix(3);  // UTF-8 byte order mark
    parse_metadata(frf);
    parse_header(frf);
    parse_rows(frf);
    apply_unit(frf);
    try {
      frf.validate();  // already guaranteed above; kept as a cheap invariant check
    } catch (const InputError& e) {
      rethrow_with_context(e, source_);
    }
    return frf;
  }

 private:
  // Advances to the next line (without '\n' and one trailing '\r').
  bool next_line() {
    if (rest_.empty()) return false;
    const size_t nl = rest_.find('\n');
    if (nl == std::string_view::npos) {
      line_ = rest_;
      rest_ = {};
    } else {
      line_ = rest_.substr(0, nl);
      rest_.remove_prefix(nl + 1);
    }
    if (!line_.empty() && line_.back() == '\r') line_.remove_suffix(1);
    ++line_no_;
    // Old Mac line ends are not supported; refusing them here keeps CR out of names and metadata.
    if (line_.find('\r') != std::string_view::npos) fail("carriage return inside the line");
    return true;
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(source_ + ": line " + std::to_string(line_no_) + ": " + what);
  }
  [[noreturn]] void fail_at(const std::string& column, const std::string& what) const {
    throw InputError(source_ + ": line " + std::to_string(line_no_) + ", column " + column + ": " + what);
  }

  void parse_metadata(FrfData& frf) {
    if (!next_line()) line_no_ = 1;
    if (is_blank(line_) && is_blank(rest_)) fail("empty file; the first line must be '# ambdiag.frf/1'");
    if (line_.empty() || line_.front() != '#' || trim(line_.substr(1)) != kFormatLine) {
      fail("the first line must be '# ambdiag.frf/1', found " + quote(line_));
    }
    while (true) {
      if (!next_line()) fail("no header line after the metadata");
      if (is_blank(line_)) {
        if (is_blank(rest_)) fail("no header line after the metadata");
        fail("empty line");
      }
      if (line_.front() != '#') return;  // the header
      const std::string_view body = line_.substr(1);
      const size_t colon = body.find(':');
      if (colon == std::string_view::npos) fail("metadata must be '# key: value', found " + quote(line_));
      const std::string key(trim(body.substr(0, colon)));
      const std::string value(trim(body.substr(colon + 1)));
      if (key.empty()) fail("metadata key is empty");
      if (frf.meta(key)) fail("metadata key '" + key + "' repeated");
      apply_known_key(frf, key, value);
      frf.metadata.emplace_back(key, value);
    }
  }

  void apply_known_key(FrfData& frf, const std::string& key, const std::string& value) {
    if (key == "speed_rpm") {
      double rpm = 0.0;
      if (const char* err = parse_double(value, rpm)) fail("speed_rpm: " + std::string(err));
      frf.speed_rpm = rpm;
    } else if (key == "quantity") {
      if (value == "compliance") {
        frf.quantity = FrfQuantity::compliance;
      } else if (value == "mobility") {
        frf.quantity = FrfQuantity::mobility;
      } else if (value == "accelerance") {
        frf.quantity = FrfQuantity::accelerance;
      } else {
        fail("quantity: unknown quantity " + quote(value) + " (compliance, mobility or accelerance)");
      }
    } else if (key == "unit") {
      if (value.empty()) fail("unit: empty");
      frf.unit = value;
    }
  }

  void parse_header(FrfData& frf) {
    header_line_ = line_no_;
    std::map<std::pair<std::string, std::string>, size_t> entry_of;  // (output, input) -> index
    std::map<std::string, size_t, std::less<>> seen;                 // column name -> index
    struct Pending {
      size_t column;
      std::string output, input;
    };
    std::vector<Pending> extras;             // sigma and coh, resolved once all H columns are known
    std::vector<std::pair<int, int>> re_im;  // per entry: column of re, of im (-1 absent)
    bool have_freq = false;

    std::string_view rest = line_;
    while (true) {
      const size_t comma = rest.find(',');
      const std::string_view cell = trim(rest.substr(0, comma));
      const size_t j = columns_.size();
      Column col;
      col.name = std::string(cell);
      if (cell.empty()) fail_at(std::to_string(j + 1), "empty column name");
      if (seen.count(col.name) != 0) fail_at(col.name, "duplicate column");
      seen.emplace(col.name, j);
      std::string output, input;
      const auto bad_pair = [&](std::string_view pair) {
        fail_at(col.name, "cannot split " + quote(pair) +
                              " into <output>_<input> (names must be non-empty and contain no '_')");
      };
      if (cell == "freq_hz") {
        col.kind = ColumnKind::freq;
        have_freq = true;
      } else if (cell.size() > 5 && cell.substr(0, 2) == "H_" &&
                 (cell.substr(cell.size() - 3) == "_re" || cell.substr(cell.size() - 3) == "_im")) {
        const std::string_view pair = cell.substr(2, cell.size() - 5);
        if (!split_pair(pair, output, input)) bad_pair(pair);
        const bool is_re = cell.substr(cell.size() - 3) == "_re";
        col.kind = is_re ? ColumnKind::re : ColumnKind::im;
        auto [it, inserted] = entry_of.try_emplace({output, input}, frf.entries.size());
        if (inserted) {
          frf.entries.push_back(FrfEntry{output, input, {}, {}, {}});
          re_im.emplace_back(-1, -1);
        }
        col.entry = it->second;
        (is_re ? re_im[col.entry].first : re_im[col.entry].second) = static_cast<int>(j);
      } else if (cell.substr(0, 6) == "sigma_" || cell.substr(0, 4) == "coh_") {
        const bool is_sigma = cell.front() == 's';
        const std::string_view pair = cell.substr(is_sigma ? 6 : 4);
        if (!split_pair(pair, output, input)) bad_pair(pair);
        col.kind = is_sigma ? ColumnKind::sigma : ColumnKind::coh;
        extras.push_back({j, output, input});
      } else {
        fail_at(col.name,
                "unknown column (expected freq_hz, H_<output>_<input>_re/_im, sigma_<output>_<input> or "
                "coh_<output>_<input>)");
      }
      columns_.push_back(std::move(col));
      if (comma == std::string_view::npos) break;
      rest.remove_prefix(comma + 1);
    }

    if (!have_freq) fail("no freq_hz column");
    if (frf.entries.empty()) fail("no H_<output>_<input>_re/_im columns");
    for (size_t e = 0; e < frf.entries.size(); ++e) {
      const auto [re, im] = re_im[e];
      if (re < 0) fail_at(columns_[static_cast<size_t>(im)].name, "no matching _re column");
      if (im < 0) fail_at(columns_[static_cast<size_t>(re)].name, "no matching _im column");
    }
    for (const Pending& p : extras) {
      const auto it = entry_of.find({p.output, p.input});
      if (it == entry_of.end()) {
        fail_at(columns_[p.column].name, "no H_" + p.output + "_" + p.input + "_re/_im columns for it");
      }
      columns_[p.column].entry = it->second;
    }
  }

  void parse_rows(FrfData& frf) {
    const size_t ncols = columns_.size();
    // Upper bound on the number of data lines, to allocate once.
    const size_t max_lines = static_cast<size_t>(std::count(rest_.begin(), rest_.end(), '\n')) + 1;
    frf.freq_hz.reserve(max_lines);
    for (auto& e : frf.entries) e.h.reserve(max_lines);
    for (const Column& c : columns_) {
      if (c.kind == ColumnKind::sigma) frf.entries[c.entry].sigma.reserve(max_lines);
      if (c.kind == ColumnKind::coh) frf.entries[c.entry].coh.reserve(max_lines);
    }
    std::vector<double> row(ncols);

    while (next_line()) {
      if (is_blank(line_)) {
        if (is_blank(rest_)) break;  // blank lines at the end are allowed
        fail("empty line");
      }
      std::string_view rest = line_;
      for (size_t j = 0; j < ncols; ++j) {
        const size_t comma = rest.find(',');
        const bool last = j + 1 == ncols;
        if (comma == std::string_view::npos && !last) {
          fail_at(columns_[j + 1].name, "missing (the line has " + std::to_string(j + 1) +
                                            " columns, the header " + std::to_string(ncols) + ")");
        }
        if (comma != std::string_view::npos && last) {
          fail("more columns than the header's " + std::to_string(ncols));
        }
        const std::string_view cell = rest.substr(0, comma);
        if (const char* err = parse_double(cell, row[j]))
          fail_at(columns_[j].name, err + (" " + quote(cell)));
        if (!last) rest.remove_prefix(comma + 1);
      }
      store_row(frf, row);
    }
    if (frf.freq_hz.empty()) {
      throw InputError(source_ + ": no data lines after the header (line " + std::to_string(header_line_) +
                       ")");
    }
  }

  void store_row(FrfData& frf, const std::vector<double>& row) {
    const size_t k = frf.freq_hz.size();
    for (auto& e : frf.entries) e.h.emplace_back();
    for (size_t j = 0; j < row.size(); ++j) {
      const Column& c = columns_[j];
      const double v = row[j];
      switch (c.kind) {
        case ColumnKind::freq:
          if (!(v > 0.0)) fail_at(c.name, "must be > 0");
          if (k > 0 && !(v > frf.freq_hz.back())) {
            fail_at(c.name,
                    "must be strictly increasing (previous line has " + shortest(frf.freq_hz.back()) + ")");
          }
          frf.freq_hz.push_back(v);
          break;
        case ColumnKind::re:
          frf.entries[c.entry].h[k].real(v);
          break;
        case ColumnKind::im:
          frf.entries[c.entry].h[k].imag(v);
          break;
        case ColumnKind::sigma:
          if (!(v >= 0.0)) fail_at(c.name, "must be >= 0");
          frf.entries[c.entry].sigma.push_back(v);
          break;
        case ColumnKind::coh:
          if (!(v >= 0.0 && v <= 1.0)) fail_at(c.name, "must be in 0..1");
          frf.entries[c.entry].coh.push_back(v);
          break;
      }
    }
  }

  // um/N and mm/N are converted to m/N (values and sigma; coherence has no unit).
  static void apply_unit(FrfData& frf) {
    double scale = 1.0;
    if (frf.unit == "um/N" || frf.unit == "\xC2\xB5m/N") {
      scale = 1e-6;
    } else if (frf.unit == "mm/N") {
      scale = 1e-3;
    } else {
      return;
    }
    for (auto& e : frf.entries) {
      for (auto& h : e.h) h *= scale;
      for (auto& s : e.sigma) s *= scale;
    }
    frf.unit = "m/N";
    frf.set_meta("unit", "m/N");
  }

  std::string_view rest_;
  std::string_view line_;
  size_t line_no_ = 0;
  size_t header_line_ = 0;
  const std::string& source_;
  std::vector<Column> columns_;
};

void check_name(const std::string& name, const char* what) {
  const bool bad = name.empty() || name.find_first_of("_,\r\n") != std::string::npos || trim(name) != name;
  if (bad) {
    throw InputError(std::string(what) + " name " + quote(name) +
                     " cannot be written to an FRF file (must be non-empty, without '_', ',', line breaks or "
                     "surrounding blanks)");
  }
}

void append_meta(std::string& out, const std::string& key, const std::string& value) {
  if (trim(key).empty() || key.find_first_of(":\r\n") != std::string::npos) {
    throw InputError("metadata key " + quote(key) +
                     " cannot be written (empty, or holds ':' or a line break)");
  }
  if (value.find_first_of("\r\n") != std::string::npos) {
    throw InputError("metadata " + key + ": value holds a line break");
  }
  out += "# ";
  out += key;
  out += ": ";
  out += value;
  out += '\n';
}

}  // namespace

FrfData parse_frf_csv(const std::string& text, const std::string& source) {
  return FrfCsvParser(text, source).parse();
}

FrfData read_frf_csv(const std::string& path) { return parse_frf_csv(read_file_bytes(path), path); }

std::string format_frf_csv(const FrfData& frf) {
  frf.validate();
  for (const auto& e : frf.entries) {
    check_name(e.output, "output");
    check_name(e.input, "input");
  }
  if (frf.unit.empty() || frf.unit.find_first_of("\r\n") != std::string::npos) {
    throw InputError("unit: must be non-empty, without line breaks");
  }

  // Fixed keys first, from the fields (which win over stale metadata), then the rest in order.
  std::string out = "# " + std::string(kFormatLine) + "\n";
  for (const char* key : {"pump_id", "run_id"}) {
    if (auto v = frf.meta(key)) append_meta(out, key, *v);
  }
  if (frf.speed_rpm) {
    if (!std::isfinite(*frf.speed_rpm)) throw InputError("speed_rpm: not finite");
    std::string v;
    append_double(v, *frf.speed_rpm);
    append_meta(out, "speed_rpm", v);
  }
  append_meta(out, "quantity", to_string(frf.quantity));
  append_meta(out, "unit", frf.unit);
  for (const auto& [key, value] : frf.metadata) {
    if (key == "pump_id" || key == "run_id" || key == "speed_rpm" || key == "quantity" || key == "unit")
      continue;
    append_meta(out, key, value);
  }

  size_t ncols = 1;
  out += "freq_hz";
  for (const auto& e : frf.entries) {
    const std::string pair = e.output + "_" + e.input;
    out += ",H_" + pair + "_re,H_" + pair + "_im";
    ncols += 2;
  }
  for (const auto& e : frf.entries) {
    if (!e.sigma.empty()) {
      out += ",sigma_" + e.output + "_" + e.input;
      ++ncols;
    }
  }
  for (const auto& e : frf.entries) {
    if (!e.coh.empty()) {
      out += ",coh_" + e.output + "_" + e.input;
      ++ncols;
    }
  }
  out += '\n';

  out.reserve(out.size() + frf.freq_hz.size() * ncols * 25);
  for (size_t k = 0; k < frf.freq_hz.size(); ++k) {
    append_double(out, frf.freq_hz[k]);
    for (const auto& e : frf.entries) {
      out += ',';
      append_double(out, e.h[k].real());
      out += ',';
      append_double(out, e.h[k].imag());
    }
    for (const auto& e : frf.entries) {
      if (e.sigma.empty()) continue;
      out += ',';
      append_double(out, e.sigma[k]);
    }
    for (const auto& e : frf.entries) {
      if (e.coh.empty()) continue;
      out += ',';
      append_double(out, e.coh[k]);
    }
    out += '\n';
  }
  return out;
}

void write_frf_csv(const std::string& path, const FrfData& frf) {
  write_file_atomic(path, format_frf_csv(frf));
}

}  // namespace ambdiag
