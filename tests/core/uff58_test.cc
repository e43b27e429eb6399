#include "ambdiag/core/uff58.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/io_util.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::data_file;
using testing::scratch_dir;
using testing::write_scratch;

std::string sample(const std::string& name) { return data_file("external/uff/" + name).string(); }

// Through memory: GCC 12 -O2 folds paired double->float->double conversions away.
double as_float(double v) {
  const volatile float f = static_cast<float>(v);
  return f;
}

// The InputError message of f(), or "" if it did not throw one.
template <typename F>
std::string refusal(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

void expect_refused(const std::string& text, const std::string& expected_part) {
  const std::string msg = refusal([&] { parse_uff58(text, "t.uff"); });
  ASSERT_FALSE(msg.empty()) << "accepted, expected refusal with: " << expected_part;
  EXPECT_NE(msg.find(expected_part), std::string::npos) << msg;
}

// A hand-written ASCII dataset 58 with the given record 7 and record 12 lines.
std::string ascii_dataset(const std::string& record7, const std::string& data) {
  return "    -1\n    58\nid one\nNONE\nNONE\nNONE\nNONE\n"
         "    1         0    0         0 NONE               0   0 NONE               0   0\n" +
         record7 +
         "\n"
         "        17    0    0    0 Time                 s                   \n"
         "         1    0    0    0 Amplitude            V                   \n"
         "         0    0    0    0 NONE                 NONE                \n"
         "         0    0    0    0 NONE                 NONE                \n" +
         data + "    -1\n";
}

// ---- the four external files

TEST(Uff58, ReadsAsciiTimeResponseSample) {
  const auto recs = read_uff58(sample("Sample_UFF58_ascii.uff"));
  ASSERT_EQ(recs.size(), 1u);
  const Uff58Record& r = recs[0];
  EXPECT_EQ(r.id1, "Mic 01.0Scalar");
  EXPECT_EQ(r.id3, "18-Apr-16 13:49:58");
  EXPECT_EQ(r.func_type, 1);
  EXPECT_EQ(r.rsp_ent_name, "Mic 01");
  EXPECT_EQ(r.rsp_dir, 1);
  EXPECT_EQ(r.ref_ent_name, "NONE");
  EXPECT_EQ(r.ord_data_type, 2);
  EXPECT_TRUE(r.even_spacing);
  EXPECT_EQ(r.x_min, 0.0);
  EXPECT_EQ(r.dx, 1.52588e-5);
  EXPECT_EQ(r.abscissa.spec_data_type, 17);
  EXPECT_EQ(r.abscissa.label, "time");
  EXPECT_EQ(r.abscissa.units, "s");
  EXPECT_EQ(r.ordinate_num.spec_data_type, 21);
  EXPECT_EQ(r.ordinate_num.label, "Pressure");
  EXPECT_EQ(r.ordinate_num.units, "Pa");
  EXPECT_EQ(r.ordinate_den.label, "NONE");
  ASSERT_EQ(r.y.size(), 79292u);
  ASSERT_EQ(r.x.size(), 79292u);
  EXPECT_EQ(r.x.back(), 79291 * 1.52588e-5);
  // First and last values as printed in the file.
  EXPECT_EQ(r.y[0], as_float(-1.47553E-02));
  EXPECT_EQ(r.y[1], as_float(-1.72957E-02));
  EXPECT_EQ(r.y[6], as_float(-1.44522E-02));
  EXPECT_EQ(r.y[79290].real(), as_float(4.43632E-04));
  EXPECT_EQ(r.y[79291].real(), as_float(-4.31469E-03));
  EXPECT_EQ(r.y[79291].imag(), 0.0);
}

TEST(Uff58, ReadsBinarySingleSampleAsTheSameSignalAsAscii) {
  const auto bin = read_uff58(sample("Sample_UFF58b_bin.uff"));
  const auto asc = read_uff58(sample("Sample_UFF58_ascii.uff"));
  ASSERT_EQ(bin.size(), 1u);
  const Uff58Record& b = bin[0];
  const Uff58Record& a = asc[0];
  EXPECT_EQ(b.ord_data_type, 2);
  EXPECT_EQ(b.func_type, 1);
  EXPECT_EQ(b.dx, a.dx);
  EXPECT_EQ(b.x_min, a.x_min);
  EXPECT_EQ(b.ordinate_num.units, "Pa");
  EXPECT_EQ(b.abscissa.units, "s");
  EXPECT_EQ(b.id1, a.id1);
  ASSERT_EQ(b.y.size(), 79292u);
  // Little-endian floats, as decoded by hand from the file's bytes.
  EXPECT_EQ(b.y[0].real(), static_cast<double>(-0.014755260199308395f));
  EXPECT_EQ(b.y.back().real(), static_cast<double>(-0.004314688965678215f));
  // The ASCII file prints the same floats with 6 significant digits.
  ASSERT_EQ(a.y.size(), b.y.size());
  for (size_t i = 0; i < a.y.size(); ++i) {
    ASSERT_NEAR(a.y[i].real(), b.y[i].real(), 5.2e-6 * std::abs(b.y[i].real())) << "point " << i;
  }
}

TEST(Uff58, ReadsBinaryDoublePrecisionSine) {
  const auto recs = read_uff58(sample("binary8byte.uff"));
  ASSERT_EQ(recs.size(), 1u);
  const Uff58Record& r = recs[0];
  EXPECT_EQ(r.ord_data_type, 4);
  EXPECT_EQ(r.func_type, 1);
  EXPECT_EQ(r.rsp_ent_name, "sine 5 Hz");
  EXPECT_EQ(r.rsp_node, 1);
  EXPECT_EQ(r.rsp_dir, 0);
  EXPECT_TRUE(r.even_spacing);
  EXPECT_EQ(r.dx, 0.01);
  EXPECT_EQ(r.x_min, 0.0);
  EXPECT_EQ(r.abscissa.label, "time (s)");
  EXPECT_EQ(r.ordinate_num.spec_data_type, 12);
  EXPECT_EQ(r.ordinate_num.label, "acc (g)");
  EXPECT_EQ(r.ordinate_num.units, "g");
  ASSERT_EQ(r.y.size(), 250u);
  EXPECT_EQ(r.y[0].real(), 0.0);
  EXPECT_EQ(r.y[1].real(), 0.30901697278022766);
  for (size_t i = 0; i < r.y.size(); ++i) {
    ASSERT_NEAR(r.y[i].real(), std::sin(2.0 * std::numbers::pi * 5.0 * r.x[i]), 1e-5) << "point " << i;
  }
}

TEST(Uff58, ReadsAsciiPsdWithUnevenAbscissa) {
  const auto recs = read_uff58(sample("sample_dataset58_psd.uff"));
  ASSERT_EQ(recs.size(), 1u);
  const Uff58Record& r = recs[0];
  EXPECT_EQ(r.id1, "Power Spectral Density (PSD)");
  EXPECT_EQ(r.id2, "VibControl Random");
  EXPECT_EQ(r.id4, "Channel 1");
  EXPECT_EQ(r.func_type, 9);
  EXPECT_EQ(r.rsp_ent_name, "Pilot 1");
  EXPECT_EQ(r.ord_data_type, 5);
  EXPECT_FALSE(r.even_spacing);
  EXPECT_EQ(r.abscissa.units, "Hz");
  EXPECT_EQ(r.ordinate_num.units, "g\xb2/Hz");  // Latin-1 superscript two, kept as the byte it is
  ASSERT_EQ(r.y.size(), 3201u);
  EXPECT_EQ(r.x[0], 0.0);
  EXPECT_EQ(r.x[1], 1.0);
  EXPECT_EQ(r.x.back(), 3200.0);
  EXPECT_EQ(r.y[0], 0.0);
  EXPECT_EQ(r.y[1], std::complex<double>(as_float(1.255863E-06), 0.0));
  EXPECT_EQ(r.y[4].real(), as_float(4.730446E-05));
  EXPECT_EQ(r.y.back(), std::complex<double>(as_float(2.634827E-10), 0.0));
}

// A truncated copy of each real file is refused, naming the file and dataset.
TEST(Uff58, RefusesTruncatedCopiesOfEachSample) {
  for (const std::string name :
       {"Sample_UFF58_ascii.uff", "Sample_UFF58b_bin.uff", "binary8byte.uff", "sample_dataset58_psd.uff"}) {
    const std::string bytes = read_file_bytes(sample(name));
    const size_t last_delim = bytes.rfind("    -1");
    ASSERT_NE(last_delim, std::string::npos);
    for (const size_t cut : {size_t{8}, size_t{100}, size_t{700}, size_t{1000}, bytes.size() / 2,
                             last_delim - 1, last_delim, last_delim + 4}) {
      if (cut >= bytes.size()) continue;
      const auto path = write_scratch("cut_" + name, bytes.substr(0, cut));
      const std::string msg = refusal([&] { read_uff58(path.string()); });
      ASSERT_FALSE(msg.empty()) << name << " cut at " << cut << " was accepted";
      EXPECT_NE(msg.find(name + ": dataset 1 ("), std::string::npos) << msg;
    }
  }
}

TEST(Uff58, NamesExpectedAndAvailableBytesOfTruncatedBinaryBlock) {
  const std::string bytes = read_file_bytes(sample("Sample_UFF58b_bin.uff"));
  size_t header_end = 0;
  for (int i = 0; i < 13; ++i) header_end = bytes.find('\n', header_end) + 1;
  const auto path = write_scratch("Sample_UFF58b_bin.uff", bytes.substr(0, header_end + 1000));
  const std::string msg = refusal([&] { read_uff58(path.string()); });
  EXPECT_NE(
      msg.find(
          "Sample_UFF58b_bin.uff: dataset 1 (58b): binary block truncated: expected 317168 bytes, got 1000"),
      std::string::npos)
      << msg;
}

// ---- parsing details and malformed input

TEST(Uff58, ParsesTouchingFieldsDExponentsAndCrlf) {
  // Full-width E20.12 fields touch; D exponents; a 3-digit exponent without its letter.
  const std::string text =
      ascii_dataset("         4         4         1  0.00000E+00  1.00000E-03  0.00000E+00",
                    "-1.000000000000E+100-2.500000000000D-101  3.000000000000E+00\n   4.0-100\n");
  std::string crlf;
  for (const char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  for (const std::string& t : {text, crlf}) {
    const auto recs = parse_uff58(t);
    ASSERT_EQ(recs.size(), 1u);
    ASSERT_EQ(recs[0].y.size(), 4u);
    EXPECT_EQ(recs[0].y[0].real(), -1e100);
    EXPECT_EQ(recs[0].y[1].real(), -2.5e-101);
    EXPECT_EQ(recs[0].y[2].real(), 3.0);
    EXPECT_EQ(recs[0].y[3].real(), 4e-100);
    EXPECT_EQ(recs[0].x[3], 3 * 1e-3);
    EXPECT_EQ(recs[0].id1, "id one");
  }
}

TEST(Uff58, SkipsOtherDatasetsAndReadsSeveral58) {
  const std::string one =
      ascii_dataset("         4         2         1  0.00000E+00  1.00000E+00  0.00000E+00",
                    "  1.000000000000E+00  2.000000000000E+00\n");
  const std::string other = "    -1\n   151\nmodel\n    -1\n    -1\n  2411\n         1         1\n    -1\n";
  const auto recs = parse_uff58(other + one + "\n" + one + other);
  ASSERT_EQ(recs.size(), 2u);
  EXPECT_EQ(recs[1].y[1].real(), 2.0);
  expect_refused(other + one + "    -1\n   151\nmodel\n",
                 "t.uff: dataset 4 (151), line 26: the file ends before");
}

TEST(Uff58, RefusesMalformedNumbers) {
  expect_refused(ascii_dataset("         2         2         1  0.00000E+00  1.00000E-03  0.00000E+00",
                               "  1.00000E+00  2.0X000E+00\n"),
                 "dataset 1 (58), line 14: record 12: '2.0X000E+00' at column 16 is not a number");
  expect_refused(
      ascii_dataset("         2         2         1  0.00000E+00  1.0000xE-03  0.00000E+00", "1 2\n"),
      "line 9: record 7: '1.0000xE-03' at column 46 is not a number");
  expect_refused(
      ascii_dataset("         2         1         1  0.00000E+00  1.00000E-03  0.00000E+00", "nan\n"),
      "'nan' at column 1 is not a number");
  expect_refused(
      ascii_dataset("         2         1         1  0.00000E+00  1.00000E-03  0.00000E+00", "1E999\n"),
      "'1E999' at column 1 is not a number");
  expect_refused(
      ascii_dataset("         2         1         1  0.00000E+00  1.00000E-03  0.00000E+00", "1E39\n"),
      "does not fit single precision");
}

TEST(Uff58, RefusesDataThatDisagreesWithRecord7) {
  const std::string three = "  1.00000E+00  2.00000E+00  3.00000E+00\n";
  expect_refused(
      ascii_dataset("         2         5         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 12: 3 values before the closing delimiter, record 7 declares 5 (5 points)");
  expect_refused(
      ascii_dataset("         2         2         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 12: more values than the 2 record 7 declares");
  expect_refused(ascii_dataset("         2         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
                 "record 7: expected 6 fields");
  expect_refused(
      ascii_dataset("         2        -5         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 7: number of points -5 must be >= 1");
  expect_refused(
      ascii_dataset("         2         0         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 7: number of points 0 must be >= 1");
  expect_refused(
      ascii_dataset("         2 9999999999         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "more than the");
  expect_refused(
      ascii_dataset("         2 4000000000000000000         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 7: number of points 4000000000000000000 does not fit I10");
  expect_refused(
      ascii_dataset("         3         3         1  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 7: unknown ordinate data type 3");
  expect_refused(
      ascii_dataset("         2         3         2  0.00000E+00  1.00000E-03  0.00000E+00", three),
      "record 7: abscissa spacing '2' must be 0 (uneven) or 1 (even)");
  expect_refused(
      ascii_dataset("         2         3         1  0.00000E+00  0.00000E+00  0.00000E+00", three),
      "must be > 0 for even spacing");
}

TEST(Uff58, RefusesMissingDelimitersAndHeaderLines) {
  const std::string good = ascii_dataset(
      "         2         1         1  0.00000E+00  1.00000E-03  0.00000E+00", "  1.00000E+00\n");
  ASSERT_EQ(parse_uff58(good).size(), 1u);
  expect_refused(good.substr(7), "t.uff: line 1: expected the dataset delimiter '    -1', found '    58'");
  expect_refused(good.substr(0, good.size() - 7),
                 "dataset 1 (58), line 14: the file ends before the closing");
  expect_refused(good + "junk\n", "t.uff: line 16: expected the dataset delimiter");
  expect_refused("    -1\n    58\nid\n    -1\n", "dataset 1 (58), line 4: the dataset ends before record 2");
  expect_refused("    -1\n", "dataset 1 (?), line 1: the file ends after the opening delimiter");
  expect_refused("    -1\n  abc\n", "dataset type 'abc' is not a positive number");
  std::string bad_rec6 = good;
  bad_rec6.replace(bad_rec6.find("    1         0"), 5, "    x");
  expect_refused(bad_rec6, "line 8: record 6: function type: 'x' is not an integer");
  EXPECT_TRUE(parse_uff58("").empty());
  EXPECT_TRUE(parse_uff58("\n\n").empty());
}

// The 58b header of a 3-point real-double record; bytes follow.
std::string binary_dataset(int byte_order, int fp_format, int64_t n_points, int64_t n_bytes,
                           const std::string& data) {
  char head[128];
  std::snprintf(head, sizeof head, "    -1\n    58b%6d%6d%12d%12lld%6d%6d%12d%12d\n", byte_order, fp_format,
                11, static_cast<long long>(n_bytes), 0, 0, 0, 0);
  char rec7[128];
  std::snprintf(rec7, sizeof rec7, "%10d%10lld%10d%13s%13s%13s\n", 4, static_cast<long long>(n_points), 1,
                "0.00000E+00", "1.00000E+00", "0.00000E+00");
  return std::string(head) + "a\nb\nc\nd\ne\n" +
         "    1         0    0         0 NONE               0   0 NONE               0   0\n" + rec7 +
         "        17    0    0    0 Time                 s                   \n"
         "         1    0    0    0 Amplitude            V                   \n"
         "         0    0    0    0 NONE                 NONE                \n"
         "         0    0    0    0 NONE                 NONE                \n" +
         data + "    -1\n";
}

std::string doubles_bytes(const std::vector<double>& v, bool big_endian) {
  std::string out;
  for (const double d : v) {
    uint64_t u = 0;
    std::memcpy(&u, &d, 8);
    for (int b = 0; b < 8; ++b) {
      const int shift = big_endian ? 8 * (7 - b) : 8 * b;
      out += static_cast<char>((u >> shift) & 0xff);
    }
  }
  return out;
}

TEST(Uff58, ReadsBigAndLittleEndianBinary) {
  const std::vector<double> v = {1.5, -2.25e-7, 3.0e100};
  for (const bool big : {false, true}) {
    const auto recs = parse_uff58(binary_dataset(big ? 2 : 1, 2, 3, 24, doubles_bytes(v, big)));
    ASSERT_EQ(recs.size(), 1u);
    ASSERT_EQ(recs[0].y.size(), 3u);
    for (size_t i = 0; i < 3; ++i) EXPECT_EQ(recs[0].y[i].real(), v[i]);
  }
}

TEST(Uff58, RefusesInconsistentBinaryHeaders) {
  const std::string data = doubles_bytes({1.0, 2.0, 3.0}, false);
  expect_refused(binary_dataset(1, 2, 3, 16, data),
                 "58b header declares 16 bytes of binary data, record 7 needs 24");
  expect_refused(binary_dataset(3, 2, 3, 24, data),
                 "byte ordering 3 must be 1 (little-endian) or 2 (big-endian)");
  expect_refused(binary_dataset(1, 3, 3, 24, data), "floating-point format 3 is not supported");
  // An absurd point count is checked against the bytes present, never allocated.
  expect_refused(binary_dataset(1, 2, 999999999, 7999999992, data),
                 "dataset 1 (58b): binary block truncated: expected 7999999992 bytes, got 31");
  expect_refused(binary_dataset(1, 2, 3, 24, doubles_bytes({1.0, NAN, 3.0}, false)),
                 "binary value 2 is not finite");
  std::string no_delim = binary_dataset(1, 2, 3, 24, data);
  no_delim.resize(no_delim.size() - 7);
  expect_refused(no_delim, "before the closing delimiter '    -1' after the binary block");
  expect_refused(binary_dataset(1, 2, 3, 24, data + "xx"),
                 "after the 24-byte binary block, found 'xx    -1'");
}

// ---- writer and round trips

Uff58Record make_record(int ord_data_type, bool even, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> expo(-30, 30);
  Uff58Record r;
  r.id1 = "round trip";
  r.id2 = "second line";
  r.id3 = "22-Nov-26 10:00:00";
  r.id4 = "NONE";
  r.id5 = "";
  r.func_type = 4;
  r.func_id = 7;
  r.version = 2;
  r.load_case_id = 3;
  r.rsp_ent_name = "rotor";
  r.rsp_node = 12;
  r.rsp_dir = -2;
  r.ref_ent_name = "amb";
  r.ref_node = 1001;
  r.ref_dir = 3;
  r.ord_data_type = ord_data_type;
  r.even_spacing = even;
  r.x_min = 0.1;
  r.dx = 1.0 / 3.0;
  r.z_axis_value = -2950.5;
  r.abscissa = {18, 0, 0, 0, "Frequency", "Hz"};
  r.ordinate_num = {8, 1, 0, 0, "Displacement", "m"};
  r.ordinate_den = {13, 0, 1, 0, "Force", "N"};
  r.z_axis = {0, 0, 0, 0, "NONE", "NONE"};
  double x = 0.1;
  for (size_t i = 0; i < n; ++i) {
    r.x.push_back(even ? r.x_min + static_cast<double>(i) * r.dx : x);
    x += 0.01 + std::abs(mant(rng));
    const double re = mant(rng) * std::pow(10.0, expo(rng));
    const double im =
        (ord_data_type == 5 || ord_data_type == 6) ? mant(rng) * std::pow(10.0, expo(rng)) : 0.0;
    r.y.emplace_back(re, im);
  }
  return r;
}

void expect_same_record(const Uff58Record& a, const Uff58Record& b) {
  EXPECT_EQ(a.id1, b.id1);
  EXPECT_EQ(a.id2, b.id2);
  EXPECT_EQ(a.id3, b.id3);
  EXPECT_EQ(a.id4, b.id4);
  EXPECT_EQ(a.id5, b.id5);
  EXPECT_EQ(a.func_type, b.func_type);
  EXPECT_EQ(a.func_id, b.func_id);
  EXPECT_EQ(a.version, b.version);
  EXPECT_EQ(a.load_case_id, b.load_case_id);
  EXPECT_EQ(a.rsp_ent_name, b.rsp_ent_name);
  EXPECT_EQ(a.rsp_node, b.rsp_node);
  EXPECT_EQ(a.rsp_dir, b.rsp_dir);
  EXPECT_EQ(a.ref_ent_name, b.ref_ent_name);
  EXPECT_EQ(a.ref_node, b.ref_node);
  EXPECT_EQ(a.ref_dir, b.ref_dir);
  EXPECT_EQ(a.ord_data_type, b.ord_data_type);
  EXPECT_EQ(a.even_spacing, b.even_spacing);
  EXPECT_EQ(a.x_min, b.x_min);
  EXPECT_EQ(a.dx, b.dx);
  EXPECT_EQ(a.z_axis_value, b.z_axis_value);
  for (auto [p, q] : {std::pair{&a.abscissa, &b.abscissa}, std::pair{&a.ordinate_num, &b.ordinate_num},
                      std::pair{&a.ordinate_den, &b.ordinate_den}, std::pair{&a.z_axis, &b.z_axis}}) {
    EXPECT_EQ(p->spec_data_type, q->spec_data_type);
    EXPECT_EQ(p->length_exp, q->length_exp);
    EXPECT_EQ(p->force_exp, q->force_exp);
    EXPECT_EQ(p->temp_exp, q->temp_exp);
    EXPECT_EQ(p->label, q->label);
    EXPECT_EQ(p->units, q->units);
  }
  ASSERT_EQ(a.x.size(), b.x.size());
  ASSERT_EQ(a.y.size(), b.y.size());
  for (size_t i = 0; i < a.y.size(); ++i) {
    ASSERT_EQ(a.x[i], b.x[i]) << "point " << i;
    ASSERT_EQ(a.y[i], b.y[i]) << "point " << i;
  }
}

// What a single-precision record holds after a trip through a file.
Uff58Record rounded_to_float(Uff58Record r) {
  for (auto& y : r.y) y = {as_float(y.real()), as_float(y.imag())};
  if (!r.even_spacing) {
    for (auto& x : r.x) x = as_float(x);
  }
  return r;
}

TEST(Uff58, RoundTripsEveryDataTypeSpacingAndEncodingLosslessly) {
  uint64_t seed = 1;
  for (const int type : {2, 4, 5, 6}) {
    for (const bool even : {true, false}) {
      for (const bool binary : {false, true}) {
        SCOPED_TRACE("type " + std::to_string(type) + (even ? " even" : " uneven") +
                     (binary ? " 58b" : " 58"));
        const Uff58Record r = make_record(type, even, 37, seed++);
        const auto back = parse_uff58(format_uff58({r, r}, binary));
        ASSERT_EQ(back.size(), 2u);
        const Uff58Record expected = (type == 2 || type == 5) ? rounded_to_float(r) : r;
        expect_same_record(back[0], expected);
        expect_same_record(back[1], expected);
      }
    }
  }
}

TEST(Uff58, WritesAndReadsAFileAtomically) {
  const Uff58Record r = make_record(6, false, 11, 42);
  const auto path = (scratch_dir() / "frf.uff").string();
  write_uff58(path, {r}, true);
  const auto back = read_uff58(path);
  ASSERT_EQ(back.size(), 1u);
  expect_same_record(back[0], r);
  const std::string msg = refusal([&] { write_uff58(path, {make_record(3, true, 2, 1)}, false); });
  EXPECT_NE(msg.find(path + ": UFF58 record 1: ordinate data type 3"), std::string::npos) << msg;
}

TEST(Uff58, WritesStandardColumnsWhenTheyHoldTheValuesExactly) {
  Uff58Record r;
  r.id1 = "Test";
  r.id2 = r.id3 = r.id4 = r.id5 = "NONE";
  r.func_type = 1;
  r.rsp_ent_name = "Mic 01";
  r.rsp_dir = 1;
  r.ord_data_type = 2;
  r.dx = 0.5;
  r.abscissa = {17, 0, 0, 0, "time", "s"};
  r.ordinate_num = {21, 0, 0, 0, "Pressure", "Pa"};
  r.ordinate_den = r.z_axis = {0, 0, 0, 0, "NONE", "NONE"};
  r.y = {1.5, -0.25, 3.0};
  EXPECT_EQ(format_uff58({r}, false),
            "    -1\n"
            "    58\n"
            "Test\nNONE\nNONE\nNONE\nNONE\n"
            "    1         0    0         0 Mic 01             0   1 NONE               0   0\n"
            "         2         3         1  0.00000E+00  5.00000E-01  0.00000E+00\n"
            "        17    0    0    0 time                 s                   \n"
            "        21    0    0    0 Pressure             Pa                  \n"
            "         0    0    0    0 NONE                 NONE                \n"
            "         0    0    0    0 NONE                 NONE                \n"
            "  1.50000E+00 -2.50000E-01  3.00000E+00\n"
            "    -1\n");
  // Doubles E20.12 holds stay standard; one it would round takes the record
  // to 17 significant digits in 25 columns.
  r.ord_data_type = 4;
  r.y = {0.25, -1e-200};
  const std::string touching = format_uff58({r}, false);
  EXPECT_NE(touching.find("\n  2.500000000000E-01-1.000000000000E-200\n"), std::string::npos) << touching;
  EXPECT_EQ(parse_uff58(touching)[0].y[1].real(), -1e-200);
  r.dx = 1.0 / 3.0;
  r.y = {0.1 + 0.2, -1e-200};
  const std::string text = format_uff58({r}, false);
  EXPECT_NE(text.find("   0.0000000000000000E+00   3.3333333333333331E-01   0.0000000000000000E+00\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("\n   3.0000000000000004E-01 -9.9999999999999998E-201\n"), std::string::npos) << text;
}

TEST(Uff58, WriterRefusesWhatTheFormatCannotHold) {
  auto msg = [](Uff58Record r) { return refusal([&] { format_uff58({r}, false); }); };
  Uff58Record r = make_record(4, true, 3, 5);
  EXPECT_EQ(msg(r), "");
  Uff58Record t = r;
  t.id2 = std::string(81, 'a');
  EXPECT_NE(msg(t).find("UFF58 record 1: id2 "), std::string::npos);
  t = r;
  t.rsp_ent_name = "eleven chars";
  EXPECT_NE(msg(t).find("response entity name 'eleven chars' is longer than 10"), std::string::npos);
  t = r;
  t.ordinate_num.units = "line\nbreak";
  EXPECT_NE(msg(t).find("contains a control character"), std::string::npos);
  t = r;
  t.y[1] = {1.0, 2.0};
  EXPECT_NE(msg(t).find("point 2 has an imaginary part but ordinate data type 4 is real"), std::string::npos);
  t = r;
  t.y[2] = NAN;
  EXPECT_NE(msg(t).find("value at point 3 is not finite"), std::string::npos);
  t = r;
  t.even_spacing = false;
  t.x.pop_back();
  EXPECT_NE(msg(t).find("uneven spacing needs one abscissa value per point"), std::string::npos);
  t = r;
  t.func_type = 123456;
  EXPECT_NE(msg(t).find("function type 123456 does not fit I5"), std::string::npos);
  t = r;
  t.ord_data_type = 2;
  t.y[0] = 1e39;
  EXPECT_NE(msg(t).find("does not fit single precision"), std::string::npos);
  t = r;
  t.y.clear();
  EXPECT_NE(msg(t).find("no data points"), std::string::npos);
}

// ---- FRF matrix mapping

FrfData make_frf(bool uniform) {
  FrfData f;
  f.metadata = {{"pump_id", "P-101"},
                {"run_id", "P-101/2026-11-21T10:00:00Z"},
                {"speed_rpm", "2950"},
                {"quantity", "compliance"},
                {"unit", "m/N"}};
  f.speed_rpm = 2950.0;
  for (int i = 0; i < 50; ++i) {
    f.freq_hz.push_back(uniform ? 5.0 + 0.25 * i : 5.0 * std::pow(1.07, i));
  }
  // Two modes seen from two sensors and two actuators: H = sum phi_o phi_i / (k - m w^2 + j c w).
  const double wn[2] = {2 * std::numbers::pi * 60.0, 2 * std::numbers::pi * 210.0};
  const double phi[2][2] = {{1.0, 0.7}, {0.4, -1.1}};
  const char* outputs[] = {"xAx", "xBy"};
  const char* inputs[] = {"fAx", "fZ"};
  for (int o = 0; o < 2; ++o) {
    for (int in = 0; in < 2; ++in) {
      FrfEntry e;
      e.output = outputs[o];
      e.input = inputs[in];
      for (const double fr : f.freq_hz) {
        const double w = 2 * std::numbers::pi * fr;
        std::complex<double> h = 0.0;
        for (int m = 0; m < 2; ++m) {
          h += phi[m][o] * phi[m][in] /
               std::complex<double>(1e7 * (1 - w * w / (wn[m] * wn[m])), 2e4 * w / wn[m]);
        }
        e.h.push_back(h);
      }
      f.entries.push_back(std::move(e));
    }
  }
  return f;
}

void expect_same_frf(const FrfData& a, const FrfData& b) {
  EXPECT_EQ(a.quantity, b.quantity);
  EXPECT_EQ(a.unit, b.unit);
  EXPECT_EQ(a.speed_rpm, b.speed_rpm);
  EXPECT_EQ(a.metadata, b.metadata);
  ASSERT_EQ(a.freq_hz, b.freq_hz);  // bit for bit
  ASSERT_EQ(a.entries.size(), b.entries.size());
  for (size_t k = 0; k < a.entries.size(); ++k) {
    EXPECT_EQ(a.entries[k].output, b.entries[k].output);
    EXPECT_EQ(a.entries[k].input, b.entries[k].input);
    EXPECT_EQ(a.entries[k].h, b.entries[k].h);
  }
}

TEST(Uff58Frf, MapsEntriesToComplexDoubleFrfRecords) {
  const FrfData f = make_frf(true);
  const auto recs = frf_to_uff58(f);
  ASSERT_EQ(recs.size(), 4u);
  const Uff58Record& r = recs[1];
  EXPECT_EQ(r.func_type, 4);
  EXPECT_EQ(r.ord_data_type, 6);
  EXPECT_TRUE(r.even_spacing);
  EXPECT_EQ(r.x_min, 5.0);
  EXPECT_EQ(r.abscissa.spec_data_type, 18);
  EXPECT_EQ(r.abscissa.units, "Hz");
  EXPECT_EQ(r.ordinate_num.spec_data_type, 8);
  EXPECT_EQ(r.ordinate_num.units, "m");
  EXPECT_EQ(r.ordinate_den.spec_data_type, 13);
  EXPECT_EQ(r.ordinate_den.units, "N");
  EXPECT_EQ(r.id1, "FRF compliance (m/N)");
  EXPECT_EQ(r.id2, "pump_id: P-101");
  EXPECT_EQ(r.id3, "run_id: P-101/2026-11-21T10:00:00Z");
  EXPECT_EQ(r.id4, "ambdiag: xAx / fZ");
  EXPECT_EQ(r.id5, "speed_rpm: 2950");
  EXPECT_EQ(r.rsp_ent_name, "xAx");
  EXPECT_EQ(r.rsp_node, 1);
  EXPECT_EQ(r.rsp_dir, 1);
  EXPECT_EQ(r.ref_ent_name, "fZ");
  EXPECT_EQ(r.ref_node, 1002);
  EXPECT_EQ(r.ref_dir, 3);
  EXPECT_EQ(recs[2].rsp_node, 2);
  EXPECT_EQ(recs[2].rsp_dir, 2);
  FrfData m = f;
  m.quantity = FrfQuantity::accelerance;
  m.unit = "m/s^2/N";
  EXPECT_EQ(frf_to_uff58(m)[0].ordinate_num.spec_data_type, 12);
  EXPECT_EQ(frf_to_uff58(m)[0].ordinate_num.units, "m/s^2");
}

TEST(Uff58Frf, RoundTripsThroughAsciiAndBinaryFilesBitForBit) {
  for (const bool uniform : {true, false}) {
    for (const bool binary : {false, true}) {
      SCOPED_TRACE(std::string(uniform ? "uniform" : "log-spaced") + (binary ? " 58b" : " 58"));
      const FrfData f = make_frf(uniform);
      const auto path = (scratch_dir() / "frf.uff").string();
      write_uff58(path, frf_to_uff58(f), binary);
      const auto recs = read_uff58(path);
      ASSERT_EQ(recs.size(), 4u);
      EXPECT_EQ(recs[0].even_spacing, uniform);
      expect_same_frf(frf_from_uff58(recs), f);
    }
  }
  FrfData mobility = make_frf(true);
  mobility.quantity = FrfQuantity::mobility;
  mobility.unit = "m/s/N";
  mobility.metadata = {{"quantity", "mobility"}, {"unit", "m/s/N"}};
  mobility.speed_rpm.reset();
  expect_same_frf(frf_from_uff58(parse_uff58(format_uff58(frf_to_uff58(mobility), false))), mobility);
}

TEST(Uff58Frf, NamesForeignFrfsFromNodesAndDropsTheDcLine) {
  Uff58Record r = make_record(6, true, 5, 9);
  r.id4 = "NONE";
  r.x_min = 0.0;
  r.dx = 2.0;
  r.x = {0.0, 2.0, 4.0, 6.0, 8.0};
  r.rsp_ent_name = "NONE";
  r.rsp_node = 12;
  r.rsp_dir = 1;
  r.ref_ent_name = "shaker 1";
  r.ref_node = 3;
  r.ref_dir = -3;
  r.ordinate_num = {12, 1, 0, 0, "Acceleration", "g"};
  Uff58Record s = r;
  s.rsp_dir = 0;
  const FrfData f = frf_from_uff58(parse_uff58(format_uff58({r, s}, false)));
  ASSERT_EQ(f.entries.size(), 2u);
  EXPECT_EQ(f.entries[0].output, "n12+X");
  EXPECT_EQ(f.entries[0].input, "shaker-1:n3-Z");
  EXPECT_EQ(f.entries[1].output, "n12");
  EXPECT_EQ(f.quantity, FrfQuantity::accelerance);
  EXPECT_EQ(f.unit, "g/N");
  EXPECT_EQ(f.freq_hz, (std::vector<double>{2.0, 4.0, 6.0, 8.0}));
  ASSERT_EQ(f.entries[0].h.size(), 4u);
  EXPECT_EQ(f.entries[0].h[0], r.y[1]);
  r.ordinate_num = {8, 1, 0, 0, "Displacement", "mm"};
  const FrfData mm = frf_from_uff58({r});
  EXPECT_EQ(mm.quantity, FrfQuantity::compliance);
  EXPECT_EQ(mm.unit, "m/N");
  EXPECT_EQ(mm.entries[0].h[0], r.y[1] * 1e-3);
}

TEST(Uff58Frf, RefusesRecordsThatAreNotOneFrfMatrix) {
  auto msg = [](const std::vector<Uff58Record>& recs) { return refusal([&] { frf_from_uff58(recs); }); };
  EXPECT_NE(
      msg(read_uff58(sample("Sample_UFF58_ascii.uff")))
          .find("UFF58 record 1: function type 1 (time response) is not a frequency response function (4)"),
      std::string::npos);
  EXPECT_NE(
      msg(read_uff58(sample("sample_dataset58_psd.uff"))).find("function type 9 (power spectral density)"),
      std::string::npos);
  EXPECT_NE(msg({}).find("no dataset 58 records"), std::string::npos);
  auto recs = frf_to_uff58(make_frf(true));
  recs[2].x[7] += 1e-9;
  EXPECT_NE(msg(recs).find("UFF58 record 3: abscissa differs from record 1's"), std::string::npos);
  recs = frf_to_uff58(make_frf(true));
  recs[3].id4 = recs[0].id4;
  EXPECT_NE(msg(recs).find("same output and input (xAx / fAx) as record 1"), std::string::npos);
  recs = frf_to_uff58(make_frf(true));
  recs[1].ordinate_num.spec_data_type = 11;
  EXPECT_NE(msg(recs).find("quantity mobility differs from record 1's compliance"), std::string::npos);
  recs = frf_to_uff58(make_frf(true));
  recs[0].abscissa.spec_data_type = 17;
  EXPECT_NE(msg(recs).find("abscissa data type 17 is not frequency (18)"), std::string::npos);
}

TEST(Uff58Frf, ExportRefusesNamesAndValuesTheMappingCannotCarry) {
  auto msg = [](const FrfData& f) { return refusal([&] { frf_to_uff58(f); }); };
  FrfData f = make_frf(true);
  f.entries[0].output = "a / b";
  EXPECT_NE(msg(f).find("contains ' / '"), std::string::npos);
  f = make_frf(true);
  f.entries[1].input = std::string(80, 'n');
  EXPECT_NE(msg(f).find("do not fit an 80-character id line"), std::string::npos);
  f = make_frf(true);
  f.entries[3].h[4] = {NAN, 0.0};
  EXPECT_NE(msg(f).find("UFF58 export: entry xBy / fZ value 4 is not finite"), std::string::npos);
  f = make_frf(true);
  f.entries[2].input = f.entries[3].input;
  EXPECT_NE(msg(f).find("entries 2 and 3 are both xBy / fZ"), std::string::npos);
  f = make_frf(true);
  f.freq_hz[0] = 0.0;
  EXPECT_NE(msg(f).find("freq_hz[0] = 0: must be finite, > 0 and increasing"), std::string::npos);
  EXPECT_NE(msg(FrfData{}).find("no FRF entries"), std::string::npos);
}

}  // namespace
}  // namespace ambdiag
