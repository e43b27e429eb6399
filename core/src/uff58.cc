// Universal File Format dataset 58 / 58b reader and writer.
//
// A universal file is a sequence of datasets, each between two lines
// `    -1`. Dataset 58 is 11 header records (ids, record 6 DOF, record 7
// data layout, records 8-11 axes) and record 12, the data; in 58b the type
// line announces a binary block that replaces record 12. docs/formats.md
// ("UFF58") lists what is read, skipped and written.
#include "ambdiag/core/uff58.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string_view>

#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"

namespace ambdiag {
namespace {

using std::string_view;

bool is_blank(char c) { return c == ' ' || c == '\t'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

string_view trim(string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

bool is_delimiter(string_view line) { return trim(line) == "-1"; }

// Columns [start, start + width) of a fixed-format line. Writers often drop
// trailing blanks, so columns past the end of the line read as blank.
string_view columns(string_view line, size_t start, size_t width) {
  if (start >= line.size()) return {};
  return line.substr(start, width);
}

// Quoted, clipped and printable, for error messages about arbitrary bytes.
std::string quote(string_view s) {
  constexpr size_t kMax = 32;
  std::string q = "'";
  for (size_t i = 0; i < std::min(s.size(), kMax); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    q += (c < 0x20 || c == 0x7f) ? '?' : static_cast<char>(c);
  }
  if (s.size() > kMax) q += "...";
  return q + "'";
}

// A Fortran real, blanks trimmed: [sign] digits [. digits] [exponent] with
// exponent E|D [sign] digits, or just sign and digits (Ew.d with a 3-digit
// exponent drops the letter: `1.00000-100`). Finite values only; an exponent
// below the double range reads as 0.
std::optional<double> to_real(string_view s) {
  constexpr size_t kMaxChars = 64;  // no real field is wider; bounds the buffer
  if (s.empty() || s.size() > kMaxChars) return std::nullopt;
  char buf[kMaxChars + 2];
  size_t n = 0, i = 0, digits = 0;
  if (s[i] == '+' || s[i] == '-') {
    if (s[i] == '-') buf[n++] = '-';
    ++i;
  }
  while (i < s.size() && is_digit(s[i])) buf[n++] = s[i++], ++digits;
  if (i < s.size() && s[i] == '.') {
    buf[n++] = s[i++];
    while (i < s.size() && is_digit(s[i])) buf[n++] = s[i++], ++digits;
  }
  if (digits == 0) return std::nullopt;
  bool negative_exponent = false;
  if (i < s.size()) {
    const char c = s[i];
    if (c == 'E' || c == 'e' || c == 'D' || c == 'd') {
      ++i;
    } else if (c != '+' && c != '-') {
      return std::nullopt;
    }
    buf[n++] = 'e';
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
      negative_exponent = s[i] == '-';
      buf[n++] = s[i++];
    }
    size_t exp_digits = 0;
    while (i < s.size() && is_digit(s[i])) buf[n++] = s[i++], ++exp_digits;
    if (exp_digits == 0 || i != s.size()) return std::nullopt;
  }
  double v = 0.0;
  const auto [end, ec] = std::from_chars(buf, buf + n, v);
  if (ec == std::errc::result_out_of_range && negative_exponent) return buf[0] == '-' ? -0.0 : 0.0;
  if (ec != std::errc() || end != buf + n || !std::isfinite(v)) return std::nullopt;
  return v;
}

// Rounds to the nearest float through memory: GCC 12's SLP vectorizer at -O2
// folds adjacent double->float->double conversions away (wrong code).
double round_to_float(double v) {
  const volatile float f = static_cast<float>(v);
  return f;
}

std::optional<int64_t> to_int(string_view s) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty() || s.front() == '+') return std::nullopt;
  int64_t v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

// Cuts a line of numbers into fields. Fields are normally blank-separated,
// but Fortran E-format lets a full-width field touch its neighbour
// (`-1.00000E+00-2.00000E+00`), so when a blank-separated token is not a
// number the line is cut at the standard column `widths` (cycled) instead.
// On failure `bad` is the first token that is not a number.
bool split_fields(string_view line, std::span<const int> widths, std::vector<string_view>& out,
                  string_view& bad) {
  out.clear();
  bad = {};
  for (size_t i = 0; i < line.size();) {
    if (is_blank(line[i])) {
      ++i;
      continue;
    }
    size_t j = i;
    while (j < line.size() && !is_blank(line[j])) ++j;
    const string_view token = line.substr(i, j - i);
    if (!to_real(token)) {
      bad = token;
      break;
    }
    out.push_back(token);
    i = j;
  }
  if (bad.empty()) return true;

  out.clear();
  size_t k = 0;
  for (size_t pos = 0; pos < line.size(); ++k) {
    const auto w = static_cast<size_t>(widths[k % widths.size()]);
    const string_view field = trim(line.substr(pos, w));
    pos += w;
    if (field.empty()) {
      if (pos >= line.size() || trim(line.substr(pos)).empty()) break;
      return false;
    }
    if (!to_real(field)) return false;
    out.push_back(field);
  }
  return true;
}

// Values per point in record 12 and their standard Fortran layout.
struct DataLayout {
  bool single;
  bool complex;
  bool even;
  int per_point() const { return (complex ? 2 : 1) + (even ? 0 : 1); }
  // One point's field widths: [x E13.5] y (E13.5 single, E20.12 double), twice if complex.
  std::vector<int> standard_widths() const {
    std::vector<int> w;
    if (!even) w.push_back(13);
    for (int i = 0; i < (complex ? 2 : 1); ++i) w.push_back(single ? 13 : 20);
    return w;
  }
};

uint32_t swap32(uint32_t v) { return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24); }
uint64_t swap64(uint64_t v) {
  return (static_cast<uint64_t>(swap32(static_cast<uint32_t>(v))) << 32) |
         swap32(static_cast<uint32_t>(v >> 32));
}

// Line-oriented reading over bytes that may hold binary blocks.
class Cursor {
 public:
  explicit Cursor(string_view bytes) : bytes_(bytes) {}
  bool at_end() const { return pos_ >= bytes_.size(); }
  size_t remaining() const { return bytes_.size() - pos_; }
  size_t line_no() const { return line_; }  // of the line returned last
  // The next line without its LF or CRLF terminator.
  string_view next_line() {
    const size_t nl = bytes_.find('\n', pos_);
    const size_t stop = nl == string_view::npos ? bytes_.size() : nl;
    string_view line = bytes_.substr(pos_, stop - pos_);
    pos_ = nl == string_view::npos ? bytes_.size() : nl + 1;
    ++line_;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return line;
  }
  // n raw bytes (n <= remaining()); newlines inside still count as lines.
  string_view take(size_t n) {
    const string_view block = bytes_.substr(pos_, n);
    line_ += static_cast<size_t>(std::count(block.begin(), block.end(), '\n'));
    pos_ += n;
    return block;
  }

 private:
  string_view bytes_;
  size_t pos_ = 0;
  size_t line_ = 0;
};

// Record 7 holds the point count in I10; blank-separated reading would take
// more digits, and the count times 3 values must not overflow.
constexpr int64_t kMaxPoints = 9'999'999'999;

class Parser {
 public:
  Parser(string_view bytes, const std::string& source) : cur_(bytes), source_(source) {}

  std::vector<Uff58Record> run() {
    std::vector<Uff58Record> records;
    while (!cur_.at_end()) {
      const string_view line = cur_.next_line();
      if (trim(line).empty()) continue;  // blank lines between datasets
      if (!is_delimiter(line)) {
        throw InputError(source_ + ": line " + std::to_string(cur_.line_no()) +
                         ": expected the dataset delimiter '    -1', found " + quote(line));
      }
      ++dataset_;
      kind_ = "?";
      if (cur_.at_end()) fail("the file ends after the opening delimiter");
      const string_view type_line = trim(cur_.next_line());
      size_t n = 0;
      while (n < type_line.size() && is_digit(type_line[n])) ++n;
      const auto type = to_int(type_line.substr(0, n));
      if (!type || *type <= 0) fail("dataset type " + quote(type_line) + " is not a positive number");
      const bool binary = n < type_line.size() && (type_line[n] == 'b' || type_line[n] == 'B');
      kind_ = std::to_string(*type) + (binary ? "b" : "");
      if (*type == 58) {
        records.push_back(read_58(binary, type_line.substr(binary ? n + 1 : n)));
      } else {
        skip_dataset();
      }
    }
    return records;
  }

 private:
  [[noreturn]] void fail(const std::string& what, bool with_line = true) const {
    std::string where = source_ + ": dataset " + std::to_string(dataset_) + " (" + kind_ + ")";
    if (with_line) where += ", line " + std::to_string(cur_.line_no());
    throw InputError(where + ": " + what);
  }

  // Datasets other than 58 are skipped to their closing delimiter.
  void skip_dataset() {
    while (!cur_.at_end()) {
      if (is_delimiter(cur_.next_line())) return;
    }
    fail("the file ends before the closing delimiter '    -1'");
  }

  string_view header_line(const char* record) {
    if (cur_.at_end()) fail(std::string("the file ends before ") + record);
    const string_view line = cur_.next_line();
    if (is_delimiter(line)) fail(std::string("the dataset ends before ") + record);
    return line;
  }

  int int_field(string_view text, const std::string& what, int64_t lo, int64_t hi) const {
    const string_view t = trim(text);
    if (t.empty()) return 0;  // Fortran reads a blank integer field as 0
    const auto v = to_int(t);
    if (!v) fail(what + ": " + quote(t) + " is not an integer");
    if (*v < lo || *v > hi) fail(what + ": " + std::to_string(*v) + " is out of range");
    return static_cast<int>(*v);
  }

  // Record 6, format 2(I5,I10),2(1X,10A1,I10,I4).
  void read_record6(Uff58Record& r) {
    const string_view l = header_line("record 6 (function and DOF identification)");
    constexpr int64_t kLo = std::numeric_limits<int>::min(), kHi = std::numeric_limits<int>::max();
    r.func_type = int_field(columns(l, 0, 5), "record 6: function type", kLo, kHi);
    r.func_id = int_field(columns(l, 5, 10), "record 6: function id", kLo, kHi);
    r.version = int_field(columns(l, 15, 5), "record 6: version number", kLo, kHi);
    r.load_case_id = int_field(columns(l, 20, 10), "record 6: load case id", kLo, kHi);
    r.rsp_ent_name = std::string(trim(columns(l, 31, 10)));
    r.rsp_node = int_field(columns(l, 41, 10), "record 6: response node", kLo, kHi);
    r.rsp_dir = int_field(columns(l, 51, 4), "record 6: response direction", kLo, kHi);
    r.ref_ent_name = std::string(trim(columns(l, 56, 10)));
    r.ref_node = int_field(columns(l, 66, 10), "record 6: reference node", kLo, kHi);
    r.ref_dir = int_field(columns(l, 76, 4), "record 6: reference direction", kLo, kHi);
  }

  // Record 7, format 3I10,3E13.5 (wider reals accepted). Returns the number of points.
  int64_t read_record7(Uff58Record& r) {
    const string_view l = header_line("record 7 (data form)");
    static constexpr int kWidths[] = {10, 10, 10, 13, 13, 13};
    std::vector<string_view> f;
    string_view bad;
    if (!split_fields(l, kWidths, f, bad)) {
      fail("record 7: " + quote(bad) + " at column " + std::to_string(bad.data() - l.data() + 1) +
           " is not a number");
    }
    if (f.size() != 6) {
      fail("record 7: expected 6 fields (data type, points, spacing, minimum, increment, z), found " +
           std::to_string(f.size()));
    }
    constexpr int64_t kLo = std::numeric_limits<int>::min(), kHi = std::numeric_limits<int>::max();
    r.ord_data_type = int_field(f[0], "record 7: ordinate data type", kLo, kHi);
    if (r.ord_data_type != 2 && r.ord_data_type != 4 && r.ord_data_type != 5 && r.ord_data_type != 6) {
      fail("record 7: unknown ordinate data type " + std::to_string(r.ord_data_type) +
           " (expected 2 real single, 4 real double, 5 complex single or 6 complex double)");
    }
    const auto n = to_int(f[1]);
    if (!n) fail("record 7: number of points " + quote(f[1]) + " is not an integer");
    if (*n < 1) fail("record 7: number of points " + std::to_string(*n) + " must be >= 1");
    if (*n > kMaxPoints) fail("record 7: number of points " + std::to_string(*n) + " does not fit I10");
    const auto spacing = to_int(f[2]);
    if (!spacing || (*spacing != 0 && *spacing != 1)) {
      fail("record 7: abscissa spacing " + quote(f[2]) + " must be 0 (uneven) or 1 (even)");
    }
    r.even_spacing = *spacing == 1;
    r.x_min = *to_real(f[3]);
    r.dx = *to_real(f[4]);
    r.z_axis_value = *to_real(f[5]);
    if (r.even_spacing && *n > 1) {
      if (!(r.dx > 0.0))
        fail("record 7: abscissa increment " + quote(f[4]) + " must be > 0 for even spacing");
      if (!std::isfinite(r.x_min + static_cast<double>(*n - 1) * r.dx)) fail("record 7: abscissa overflows");
    }
    return *n;
  }

  // Records 8-11, format I10,3I5,2(1X,20A1).
  UffAxis read_axis(int record) {
    const std::string rec = "record " + std::to_string(record);
    const string_view l = header_line((rec + " (axis)").c_str());
    constexpr int64_t kLo = std::numeric_limits<int>::min(), kHi = std::numeric_limits<int>::max();
    UffAxis a;
    a.spec_data_type = int_field(columns(l, 0, 10), rec + ": specific data type", kLo, kHi);
    a.length_exp = int_field(columns(l, 10, 5), rec + ": length units exponent", kLo, kHi);
    a.force_exp = int_field(columns(l, 15, 5), rec + ": force units exponent", kLo, kHi);
    a.temp_exp = int_field(columns(l, 20, 5), rec + ": temperature units exponent", kLo, kHi);
    a.label = std::string(trim(columns(l, 26, 20)));
    a.units = std::string(trim(columns(l, 47, 20)));
    return a;
  }

  struct BinaryHeader {
    bool big_endian = false;
    int64_t n_bytes = 0;
  };

  // The rest of a 58b type line: byte ordering, floating-point format, ASCII
  // header lines, bytes of binary data (I6,I6,I12,I12), then unused fields.
  BinaryHeader read_binary_header(string_view rest) {
    static constexpr int kWidths[] = {6, 6, 12, 12, 6, 6, 12, 12};
    std::vector<string_view> f;
    string_view bad;
    if (!split_fields(rest, kWidths, f, bad) || f.size() < 4) {
      fail("58b header: expected byte ordering, floating-point format, header lines and byte count");
    }
    std::optional<int64_t> v[4];
    for (int i = 0; i < 4; ++i) {
      v[i] = to_int(f[static_cast<size_t>(i)]);
      if (!v[i]) fail("58b header: " + quote(f[static_cast<size_t>(i)]) + " is not an integer");
    }
    if (*v[0] != 1 && *v[0] != 2) {
      fail("58b header: byte ordering " + std::to_string(*v[0]) +
           " must be 1 (little-endian) or 2 (big-endian)");
    }
    if (*v[1] != 2) {
      fail("58b header: floating-point format " + std::to_string(*v[1]) +
           " is not supported (only 2, IEEE 754; 1 is DEC VMS, 3 IBM 370)");
    }
    if (*v[2] != 11) fail("58b header: " + std::to_string(*v[2]) + " ASCII header lines, dataset 58b has 11");
    if (*v[3] < 0) fail("58b header: byte count " + std::to_string(*v[3]) + " must be >= 0");
    return {*v[0] == 2, *v[3]};
  }

  std::vector<double> read_ascii_data(const DataLayout& layout, int64_t n_points, int64_t n_values) {
    // Every value takes at least one byte: a count beyond that is a lie
    // (or truncation) and must not size an allocation.
    if (static_cast<uint64_t>(n_values) > cur_.remaining()) {
      fail("record 7 declares " + std::to_string(n_points) + " points (" + std::to_string(n_values) +
           " values), more than the " + std::to_string(cur_.remaining()) + " bytes left can hold");
    }
    const auto needed = static_cast<size_t>(n_values);
    const std::vector<int> widths = layout.standard_widths();
    std::vector<double> values;
    values.reserve(std::min(needed, cur_.remaining() / 2 + 1));
    std::vector<string_view> fields;
    string_view bad;
    while (true) {
      if (cur_.at_end()) {
        if (values.size() < needed) {
          fail("data truncated: the file ends after " + std::to_string(values.size()) + " of " +
               std::to_string(needed) + " values (record 7: " + std::to_string(n_points) + " points)");
        }
        fail("the file ends before the closing delimiter '    -1'");
      }
      const string_view line = cur_.next_line();
      if (is_delimiter(line)) break;
      if (!split_fields(line, widths, fields, bad)) {
        fail("record 12: " + quote(bad) + " at column " + std::to_string(bad.data() - line.data() + 1) +
             " is not a number");
      }
      if (values.size() + fields.size() > needed) {
        fail("record 12: more values than the " + std::to_string(needed) + " record 7 declares (" +
             std::to_string(n_points) + " points)");
      }
      for (const string_view f : fields) values.push_back(*to_real(f));
    }
    if (values.size() < needed) {
      fail("record 12: " + std::to_string(values.size()) +
           " values before the closing delimiter, record 7 declares " + std::to_string(needed) + " (" +
           std::to_string(n_points) + " points)");
    }
    return values;
  }

  std::vector<double> read_binary_data(const DataLayout& layout, const BinaryHeader& h, int64_t n_points,
                                       int64_t n_values) {
    const int64_t value_bytes = layout.single ? 4 : 8;
    if (h.n_bytes != n_values * value_bytes) {
      fail("58b header declares " + std::to_string(h.n_bytes) + " bytes of binary data, record 7 needs " +
           std::to_string(n_values * value_bytes) + " (" + std::to_string(n_points) + " points of " +
           std::to_string(layout.per_point()) + " x " + std::to_string(value_bytes) + " bytes)");
    }
    if (static_cast<uint64_t>(h.n_bytes) > cur_.remaining()) {
      fail("binary block truncated: expected " + std::to_string(h.n_bytes) + " bytes, got " +
               std::to_string(cur_.remaining()),
           false);
    }
    const string_view block = cur_.take(static_cast<size_t>(h.n_bytes));
    const bool swap = h.big_endian != (std::endian::native == std::endian::big);
    std::vector<double> values(static_cast<size_t>(n_values));
    for (size_t i = 0; i < values.size(); ++i) {
      if (layout.single) {
        uint32_t u = 0;
        std::memcpy(&u, block.data() + 4 * i, 4);
        values[i] = std::bit_cast<float>(swap ? swap32(u) : u);
      } else {
        uint64_t u = 0;
        std::memcpy(&u, block.data() + 8 * i, 8);
        values[i] = std::bit_cast<double>(swap ? swap64(u) : u);
      }
      if (!std::isfinite(values[i])) fail("binary value " + std::to_string(i + 1) + " is not finite", false);
    }
    // The delimiter follows the block directly; some writers put a line break first.
    if (cur_.at_end()) fail("the file ends before the closing delimiter '    -1' after the binary block");
    string_view line = cur_.next_line();
    if (line.empty() && !cur_.at_end()) line = cur_.next_line();
    if (!is_delimiter(line)) {
      fail("expected the closing delimiter '    -1' after the " + std::to_string(h.n_bytes) +
           "-byte binary block, found " + quote(line));
    }
    return values;
  }

  Uff58Record read_58(bool binary, string_view type_rest) {
    BinaryHeader bh;
    if (binary) bh = read_binary_header(type_rest);
    Uff58Record r;
    std::string* ids[] = {&r.id1, &r.id2, &r.id3, &r.id4, &r.id5};
    for (int i = 0; i < 5; ++i) {
      const std::string rec = "record " + std::to_string(i + 1) + " (id line)";
      *ids[i] = std::string(trim(header_line(rec.c_str())));
    }
    read_record6(r);
    const int64_t n_points = read_record7(r);
    r.abscissa = read_axis(8);
    r.ordinate_num = read_axis(9);
    r.ordinate_den = read_axis(10);
    r.z_axis = read_axis(11);

    const DataLayout layout{!r.is_double(), r.is_complex(), r.even_spacing};
    const int64_t n_values = n_points * layout.per_point();  // n_points <= kMaxPoints: no overflow
    std::vector<double> v = binary ? read_binary_data(layout, bh, n_points, n_values)
                                   : read_ascii_data(layout, n_points, n_values);
    if (layout.single) {
      for (size_t i = 0; i < v.size(); ++i) {
        if (std::abs(v[i]) > std::numeric_limits<float>::max()) {
          fail("value " + std::to_string(i + 1) + " does not fit single precision (ordinate data type " +
               std::to_string(r.ord_data_type) + ")");
        }
        v[i] = round_to_float(v[i]);
      }
    }

    const auto n = static_cast<size_t>(n_points);
    const auto per = static_cast<size_t>(layout.per_point());
    r.x.resize(n);
    r.y.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const double* p = v.data() + per * i;
      r.x[i] = layout.even ? r.x_min + static_cast<double>(i) * r.dx : *p++;
      r.y[i] = layout.complex ? std::complex<double>(p[0], p[1]) : std::complex<double>(p[0], 0.0);
    }
    return r;
  }

  Cursor cur_;
  const std::string& source_;
  int dataset_ = 0;   // 1-based, counting every dataset of the file
  std::string kind_;  // "58", "58b", "151", ...
};

// ---- writer

// A Fortran Ew.d field: d digits after the point.
struct RealField {
  int width;
  int digits;
};
// Standard widths, and the wider ones that hold every float (9 significant
// digits) and every double (17) exactly, always with a blank in front.
constexpr RealField kE13{13, 5}, kE20{20, 12}, kE16{16, 8}, kE25{25, 16};
constexpr int kLineWidth = 80;

// Writes v as E-format into buf (>= 32 chars), returns the length.
size_t e_format(char* buf, double v, int digits) {
  const auto res = std::to_chars(buf, buf + 32, v, std::chars_format::scientific, digits);
  for (char* p = buf; p != res.ptr; ++p) {
    if (*p == 'e') *p = 'E';
  }
  return static_cast<size_t>(res.ptr - buf);
}

void append_real(std::string& out, double v, RealField f) {
  char buf[32];
  const size_t len = e_format(buf, v, f.digits);
  if (len < static_cast<size_t>(f.width)) out.append(static_cast<size_t>(f.width) - len, ' ');
  out.append(buf, len);
}

// Whether v survives writing in field f and reading back (as float if single).
bool exact_in(double v, RealField f, bool single) {
  char buf[32];
  const size_t len = e_format(buf, v, f.digits);
  const auto back = to_real(string_view(buf, len));
  if (!back || len > static_cast<size_t>(f.width)) return false;
  return single ? static_cast<float>(*back) == static_cast<float>(v) : *back == v;
}

void append_int(std::string& out, int64_t v, int width) {
  const std::string s = std::to_string(v);
  if (s.size() < static_cast<size_t>(width)) out.append(static_cast<size_t>(width) - s.size(), ' ');
  out += s;
}

void append_text(std::string& out, const std::string& s, size_t width) {
  out += s;
  if (s.size() < width) out.append(width - s.size(), ' ');
}

class Writer {
 public:
  Writer(const Uff58Record& r, size_t index) : r_(r), index_(index) {}

  void write(std::string& out, bool binary) {
    check();
    const DataLayout layout{!r_.is_double(), r_.is_complex(), r_.even_spacing};
    const std::vector<double> v = values(layout);
    out += "    -1\n";
    if (binary) {
      const int64_t n_bytes = static_cast<int64_t>(v.size()) * (layout.single ? 4 : 8);
      out += "    58b";
      append_int(out, 1, 6);  // little-endian
      append_int(out, 2, 6);  // IEEE 754
      append_int(out, 11, 12);
      append_int(out, n_bytes, 12);
      append_int(out, 0, 6);
      append_int(out, 0, 6);
      append_int(out, 0, 12);
      append_int(out, 0, 12);
      out += '\n';
    } else {
      out += "    58\n";
    }
    for (const std::string* id : {&id_[0], &id_[1], &id_[2], &id_[3], &id_[4]}) out += *id + '\n';
    // Record 6: 2(I5,I10),2(1X,10A1,I10,I4).
    append_int(out, r_.func_type, 5);
    append_int(out, r_.func_id, 10);
    append_int(out, r_.version, 5);
    append_int(out, r_.load_case_id, 10);
    out += ' ';
    append_text(out, rsp_, 10);
    append_int(out, r_.rsp_node, 10);
    append_int(out, r_.rsp_dir, 4);
    out += ' ';
    append_text(out, ref_, 10);
    append_int(out, r_.ref_node, 10);
    append_int(out, r_.ref_dir, 4);
    out += '\n';
    // Record 7: 3I10,3E13.5, or 3E25.16 when E13.5 would round.
    append_int(out, r_.ord_data_type, 10);
    append_int(out, static_cast<int64_t>(r_.y.size()), 10);
    append_int(out, r_.even_spacing ? 1 : 0, 10);
    const double r7[] = {r_.x_min, r_.dx, r_.z_axis_value};
    const bool r7_std =
        std::all_of(std::begin(r7), std::end(r7), [](double d) { return exact_in(d, kE13, false); });
    for (const double d : r7) append_real(out, d, r7_std ? kE13 : kE25);
    out += '\n';
    for (int i = 0; i < 4; ++i) {
      const UffAxis& a = *axes_[i];
      append_int(out, a.spec_data_type, 10);
      append_int(out, a.length_exp, 5);
      append_int(out, a.force_exp, 5);
      append_int(out, a.temp_exp, 5);
      out += ' ';
      append_text(out, labels_[i][0], 20);
      out += ' ';
      append_text(out, labels_[i][1], 20);
      out += '\n';
    }
    if (binary) {
      append_binary(out, v, layout.single);
    } else {
      append_ascii(out, v, layout);
    }
    out += "    -1\n";
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("UFF58 record " + std::to_string(index_ + 1) + ": " + what);
  }

  std::string text(const std::string& s, size_t max, const char* name) const {
    const std::string t(trim(s));
    if (t.size() > max)
      fail(std::string(name) + " " + quote(t) + " is longer than " + std::to_string(max) + " characters");
    for (const char c : t) {
      const auto u = static_cast<unsigned char>(c);
      if (u < 0x20 || u == 0x7f) fail(std::string(name) + " " + quote(t) + " contains a control character");
    }
    return t;
  }

  void int_fits(int64_t v, int width, const char* name) const {
    int64_t hi = 1;
    for (int i = 0; i < width; ++i) hi *= 10;
    if (v >= hi || v <= -hi / 10)
      fail(std::string(name) + " " + std::to_string(v) + " does not fit I" + std::to_string(width));
  }

  void check() {
    const std::string* ids[] = {&r_.id1, &r_.id2, &r_.id3, &r_.id4, &r_.id5};
    for (int i = 0; i < 5; ++i) id_[i] = text(*ids[i], 80, ("id" + std::to_string(i + 1)).c_str());
    rsp_ = text(r_.rsp_ent_name, 10, "response entity name");
    ref_ = text(r_.ref_ent_name, 10, "reference entity name");
    int_fits(r_.func_type, 5, "function type");
    int_fits(r_.func_id, 10, "function id");
    int_fits(r_.version, 5, "version number");
    int_fits(r_.load_case_id, 10, "load case id");
    int_fits(r_.rsp_node, 10, "response node");
    int_fits(r_.rsp_dir, 4, "response direction");
    int_fits(r_.ref_node, 10, "reference node");
    int_fits(r_.ref_dir, 4, "reference direction");
    static const char* kAxisNames[] = {"abscissa", "ordinate numerator", "ordinate denominator", "z axis"};
    for (int i = 0; i < 4; ++i) {
      const UffAxis& a = *axes_[i];
      const std::string name = kAxisNames[i];
      int_fits(a.spec_data_type, 10, (name + " data type").c_str());
      int_fits(a.length_exp, 5, (name + " length exponent").c_str());
      int_fits(a.force_exp, 5, (name + " force exponent").c_str());
      int_fits(a.temp_exp, 5, (name + " temperature exponent").c_str());
      labels_[i][0] = text(a.label, 20, (name + " label").c_str());
      labels_[i][1] = text(a.units, 20, (name + " units").c_str());
    }
    const int t = r_.ord_data_type;
    if (t != 2 && t != 4 && t != 5 && t != 6) {
      fail("ordinate data type " + std::to_string(t) + " is not 2, 4, 5 or 6");
    }
    const size_t n = r_.y.size();
    if (n == 0) fail("no data points");
    if (n > 999999999) fail(std::to_string(n) + " points do not fit record 7");
    if (!std::isfinite(r_.x_min) || !std::isfinite(r_.dx) || !std::isfinite(r_.z_axis_value)) {
      fail("record 7 values (minimum, increment, z) must be finite");
    }
    if (r_.even_spacing) {
      if (n > 1 && !(r_.dx > 0.0)) fail("abscissa increment must be > 0 for even spacing");
      if (!std::isfinite(r_.x_min + static_cast<double>(n - 1) * r_.dx)) fail("abscissa overflows");
    } else if (r_.x.size() != n) {
      fail("uneven spacing needs one abscissa value per point (" + std::to_string(r_.x.size()) + " for " +
           std::to_string(n) + " points)");
    }
  }

  // Record 12 values in file order: [x] re [im] per point, checked.
  std::vector<double> values(const DataLayout& layout) const {
    std::vector<double> v;
    v.reserve(r_.y.size() * static_cast<size_t>(layout.per_point()));
    auto push = [&](double d, size_t i) {
      if (!std::isfinite(d)) fail("value at point " + std::to_string(i + 1) + " is not finite");
      if (layout.single) {
        if (std::abs(d) > std::numeric_limits<float>::max()) {
          fail("value at point " + std::to_string(i + 1) + " does not fit single precision");
        }
        d = round_to_float(d);
      }
      v.push_back(d);
    };
    for (size_t i = 0; i < r_.y.size(); ++i) {
      if (!layout.even) push(r_.x[i], i);
      push(r_.y[i].real(), i);
      if (layout.complex) {
        push(r_.y[i].imag(), i);
      } else if (r_.y[i].imag() != 0.0) {
        fail("point " + std::to_string(i + 1) + " has an imaginary part but ordinate data type " +
             std::to_string(r_.ord_data_type) + " is real");
      }
    }
    return v;
  }

  static void append_binary(std::string& out, const std::vector<double>& v, bool single) {
    out.reserve(out.size() + v.size() * (single ? 4 : 8) + 16);
    for (const double d : v) {
      if (single) {
        const auto u = std::bit_cast<uint32_t>(static_cast<float>(d));
        for (int b = 0; b < 4; ++b) out += static_cast<char>((u >> (8 * b)) & 0xffu);
      } else {
        const auto u = std::bit_cast<uint64_t>(d);
        for (int b = 0; b < 8; ++b) out += static_cast<char>((u >> (8 * b)) & 0xffu);
      }
    }
  }

  // Standard layout (E13.5 abscissa, E13.5 / E20.12 ordinate) when it holds
  // every value exactly; otherwise E16.8 / E25.16 for all, which does.
  static void append_ascii(std::string& out, const std::vector<double>& v, const DataLayout& layout) {
    const size_t per = static_cast<size_t>(layout.per_point());
    const RealField y_std = layout.single ? kE13 : kE20;
    bool standard = true;
    for (size_t i = 0; i < v.size() && standard; ++i) {
      const bool is_x = !layout.even && i % per == 0;
      standard = exact_in(v[i], is_x ? kE13 : y_std, layout.single);
    }
    const RealField wide = layout.single ? kE16 : kE25;
    const RealField x_field = standard ? kE13 : wide;
    const RealField y_field = standard ? y_std : wide;
    const int point_width = (layout.even ? 0 : x_field.width) + (layout.complex ? 2 : 1) * y_field.width;
    const size_t points_per_line = static_cast<size_t>(std::max(1, kLineWidth / point_width));
    const size_t n_points = v.size() / per;
    for (size_t p = 0; p < n_points; ++p) {
      for (size_t k = 0; k < per; ++k) {
        append_real(out, v[p * per + k], (!layout.even && k == 0) ? x_field : y_field);
      }
      if ((p + 1) % points_per_line == 0 || p + 1 == n_points) out += '\n';
    }
  }

  const Uff58Record& r_;
  size_t index_;
  std::string id_[5], rsp_, ref_;
  std::string labels_[4][2];
  const UffAxis* axes_[4] = {&r_.abscissa, &r_.ordinate_num, &r_.ordinate_den, &r_.z_axis};
};

}  // namespace

std::vector<Uff58Record> parse_uff58(const std::string& bytes, const std::string& source) {
  return Parser(bytes, source).run();
}

std::vector<Uff58Record> read_uff58(const std::string& path) {
  return parse_uff58(read_file_bytes(path), path);
}

std::string format_uff58(const std::vector<Uff58Record>& records, bool binary) {
  std::string out;
  for (size_t i = 0; i < records.size(); ++i) Writer(records[i], i).write(out, binary);
  return out;
}

void write_uff58(const std::string& path, const std::vector<Uff58Record>& records, bool binary) {
  std::string bytes;
  try {
    bytes = format_uff58(records, binary);
  } catch (const InputError& e) {
    rethrow_with_context(e, path);
  }
  write_file_atomic(path, bytes);
}

}  // namespace ambdiag
