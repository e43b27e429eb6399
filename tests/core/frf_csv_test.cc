#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using ambdiag::testing::data_file;
using ambdiag::testing::scratch_dir;
using ambdiag::testing::write_scratch;

// Three lines, two entries, sigma and coherence on the first. Data on lines 6..8.
const std::string kSmall =
    "# ambdiag.frf/1\n"
    "# pump_id: P-1\n"
    "# quantity: compliance\n"
    "# unit: m/N\n"
    "freq_hz,H_xAx_fAx_re,H_xAx_fAx_im,H_xAy_fAx_re,H_xAy_fAx_im,sigma_xAx_fAx,coh_xAx_fAx\n"
    "1,1e-7,-2e-8,3e-8,4e-9,1e-9,0.9\n"
    "2,2e-7,-3e-8,4e-8,5e-9,2e-9,0.95\n"
    "3,3e-7,-4e-8,5e-8,6e-9,3e-9,1\n";

// kSmall with (1-based) line `n` replaced.
std::string with_line(int n, const std::string& line) {
  std::string out;
  size_t pos = 0;
  for (int i = 1; pos < kSmall.size(); ++i) {
    const size_t nl = kSmall.find('\n', pos);
    out += (i == n) ? line : kSmall.substr(pos, nl - pos);
    out += '\n';
    pos = nl + 1;
  }
  return out;
}

std::string error_of(const std::string& text) {
  try {
    parse_frf_csv(text, "frf.csv");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<accepted>";
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_bit_identical(const FrfData& a, const FrfData& b) {
  ASSERT_EQ(a.freq_hz.size(), b.freq_hz.size());
  ASSERT_EQ(a.entries.size(), b.entries.size());
  for (size_t k = 0; k < a.freq_hz.size(); ++k) EXPECT_TRUE(same_bits(a.freq_hz[k], b.freq_hz[k])) << k;
  for (size_t i = 0; i < a.entries.size(); ++i) {
    const FrfEntry& x = a.entries[i];
    const FrfEntry& y = b.entries[i];
    EXPECT_EQ(x.output, y.output);
    EXPECT_EQ(x.input, y.input);
    ASSERT_EQ(x.h.size(), y.h.size());
    ASSERT_EQ(x.sigma.size(), y.sigma.size());
    ASSERT_EQ(x.coh.size(), y.coh.size());
    for (size_t k = 0; k < x.h.size(); ++k) {
      EXPECT_TRUE(same_bits(x.h[k].real(), y.h[k].real()) && same_bits(x.h[k].imag(), y.h[k].imag()))
          << "entry " << i << " line " << k;
    }
    for (size_t k = 0; k < x.sigma.size(); ++k) EXPECT_TRUE(same_bits(x.sigma[k], y.sigma[k]));
    for (size_t k = 0; k < x.coh.size(); ++k) EXPECT_TRUE(same_bits(x.coh[k], y.coh[k]));
  }
  EXPECT_EQ(a.quantity, b.quantity);
  EXPECT_EQ(a.unit, b.unit);
  EXPECT_EQ(a.speed_rpm.has_value(), b.speed_rpm.has_value());
  if (a.speed_rpm && b.speed_rpm) {
    EXPECT_TRUE(same_bits(*a.speed_rpm, *b.speed_rpm));
  }
}

// --- the shared files -------------------------------------------------------

struct SharedFrf {
  const char* path;
  size_t entries;
  size_t lines;
  bool sigma;
  FrfQuantity quantity;
};

class SharedFrfFile : public ::testing::TestWithParam<SharedFrf> {};

TEST_P(SharedFrfFile, ParsesWithTheExpectedEntriesAndLines) {
  const SharedFrf& p = GetParam();
  const FrfData frf = read_frf_csv(data_file(p.path).string());
  EXPECT_EQ(frf.entries.size(), p.entries);
  EXPECT_EQ(frf.freq_hz.size(), p.lines);
  EXPECT_EQ(frf.quantity, p.quantity);
  for (const auto& e : frf.entries) {
    EXPECT_EQ(e.h.size(), p.lines);
    EXPECT_EQ(e.sigma.size(), p.sigma ? p.lines : 0u);
    EXPECT_TRUE(e.coh.empty());
  }
  EXPECT_NO_THROW(frf.validate());
}

const SharedFrf kSharedFrfs[] = {
    {"reference_pump/frf_ref_1.csv", 25, 1000, true, FrfQuantity::compliance},
    {"reference_pump/frf_ref_2.csv", 25, 1000, true, FrfQuantity::compliance},
    {"reference_pump/frf_ref_3.csv", 25, 1000, true, FrfQuantity::compliance},
    {"reference_pump/frf_ref_4.csv", 25, 1000, true, FrfQuantity::compliance},
    {"reference_pump/frf_ref_5.csv", 25, 1000, true, FrfQuantity::compliance},
    {"reference_pump/run_stepsine/frf_truth.csv", 25, 60, false, FrfQuantity::compliance},
    {"fault_dry_run/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"fault_balance_piston_wear/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"fault_crack/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"explain_cross_coupling/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"explain_delay/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"explain_none/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"explain_paper_table3/frf.csv", 25, 1000, true, FrfQuantity::compliance},
    {"ident_7mode/frf.csv", 1, 2000, true, FrfQuantity::compliance},
    {"external/pyuff_meas_point_1/frf.csv", 1, 1000, false, FrfQuantity::accelerance},
};
INSTANTIATE_TEST_SUITE_P(FrfCsv, SharedFrfFile, ::testing::ValuesIn(kSharedFrfs));

TEST(FrfCsv, ReadsThePumpMatrixWithMetadataMirroredInFields) {
  const FrfData frf = read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string());
  EXPECT_EQ(frf.meta("pump_id"), "P-101");
  ASSERT_TRUE(frf.speed_rpm.has_value());
  EXPECT_EQ(*frf.speed_rpm, 2950.0);
  EXPECT_EQ(frf.unit, "m/N");
  EXPECT_EQ(frf.outputs(), (std::vector<std::string>{"xAx", "xAy", "xBx", "xBy", "xZ"}));
  EXPECT_EQ(frf.inputs(), (std::vector<std::string>{"fAx", "fAy", "fBx", "fBy", "fZ"}));
  ASSERT_NE(frf.find("xBy", "fZ"), nullptr);
  EXPECT_EQ(frf.find("fZ", "xBy"), nullptr);
}

TEST(FrfCsv, KeepsUnknownMetadataAndUnknownUnits) {
  const FrfData note = read_frf_csv(data_file("reference_pump/run_stepsine/frf_truth.csv").string());
  EXPECT_EQ(note.meta("note"), "noise-free truth at the step frequencies of samples.f32");
  const FrfData ext = read_frf_csv(data_file("external/pyuff_meas_point_1/frf.csv").string());
  EXPECT_EQ(ext.unit, "unknown");
  EXPECT_FALSE(ext.speed_rpm.has_value());
  ASSERT_GE(ext.metadata.size(), 3u);
  EXPECT_EQ(ext.metadata[0].first, "source");
}

TEST(FrfCsv, ReadsOneSharedPumpFileInWellUnder50Ms) {
  const std::string path = data_file("reference_pump/frf_ref_1.csv").string();
  double best_ms = 1e9;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const FrfData frf = read_frf_csv(path);
    const auto t1 = std::chrono::steady_clock::now();
    ASSERT_EQ(frf.freq_hz.size(), 1000u);
    best_ms = std::min(best_ms, std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
  std::printf("read %s: %.2f ms\n", path.c_str(), best_ms);
#if defined(NDEBUG) && !defined(__SANITIZE_ADDRESS__)
  EXPECT_LT(best_ms, 50.0);
#endif
}

// --- round trips ------------------------------------------------------------

TEST(FrfCsv, RoundTripOfASharedFileIsBitIdentical) {
  const FrfData frf = read_frf_csv(data_file("reference_pump/frf_ref_2.csv").string());
  const auto path = scratch_dir() / "frf.csv";
  write_frf_csv(path.string(), frf);
  const FrfData back = read_frf_csv(path.string());
  expect_bit_identical(frf, back);
  EXPECT_EQ(back.metadata, frf.metadata);
}

TEST(FrfCsv, RoundTripKeepsAwkwardDoublesBitIdentical) {
  const double awkward[] = {0.1,
                            1.0 / 3.0,
                            -0.0,
                            5e-324,
                            std::numeric_limits<double>::min(),
                            std::numeric_limits<double>::max(),
                            -1.2345678901234567e-300,
                            std::nextafter(1.0, 2.0)};
  FrfData frf;
  frf.speed_rpm = 2950.123456789012;
  frf.quantity = FrfQuantity::mobility;
  frf.unit = "(m/s)/N";
  frf.set_meta("run_id", "P-1/x");
  frf.set_meta("operator", "a: b");  // a colon in the value survives
  FrfEntry a{"xAx", "fAx", {}, {}, {}};
  FrfEntry b{"xZ", "fZ", {}, {}, {}};
  for (size_t k = 0; k < std::size(awkward); ++k) {
    frf.freq_hz.push_back(0.1 + static_cast<double>(k) / 3.0);
    a.h.emplace_back(awkward[k], -awkward[std::size(awkward) - 1 - k]);
    b.h.emplace_back(std::sqrt(static_cast<double>(k) + 2.0), awkward[k]);
    b.sigma.push_back(std::fabs(awkward[k]));
    b.coh.push_back(static_cast<double>(k) / 7.0);
  }
  frf.entries = {a, b};
  const FrfData back = parse_frf_csv(format_frf_csv(frf));
  expect_bit_identical(frf, back);
  EXPECT_EQ(back.meta("operator"), "a: b");
  EXPECT_EQ(back.meta("run_id"), "P-1/x");
}

TEST(FrfCsv, WriterPutsFixedKeysFirstThenHThenSigmaThenCoherence) {
  FrfData frf;
  frf.set_meta("zeta", "last");
  frf.set_meta("run_id", "R");
  frf.set_meta("pump_id", "P");
  frf.speed_rpm = 100;
  frf.freq_hz = {1.5};
  frf.entries = {FrfEntry{"x1", "f1", {{1, 2}}, {}, {0.5}}, FrfEntry{"x2", "f1", {{3, 4}}, {0.25}, {}}};
  EXPECT_EQ(format_frf_csv(frf),
            "# ambdiag.frf/1\n"
            "# pump_id: P\n"
            "# run_id: R\n"
            "# speed_rpm: 100\n"
            "# quantity: compliance\n"
            "# unit: m/N\n"
            "# zeta: last\n"
            "freq_hz,H_x1_f1_re,H_x1_f1_im,H_x2_f1_re,H_x2_f1_im,sigma_x2_f1,coh_x1_f1\n"
            "1.5,1,2,3,4,0.25,0.5\n");
}

TEST(FrfCsv, WriterUsesSeventeenSignificantDigits) {
  FrfData frf;
  frf.freq_hz = {0.1};
  frf.entries = {FrfEntry{"x", "f", {{1.0 / 3.0, 0}}, {}, {}}};
  const std::string text = format_frf_csv(frf);
  EXPECT_TRUE(contains(text, "\n0.10000000000000001,0.33333333333333331,0\n")) << text;
}

TEST(FrfCsv, WriterRefusesNamesItCouldNotReadBack) {
  FrfData frf;
  frf.freq_hz = {1};
  frf.entries = {FrfEntry{"x_A", "f", {{1, 2}}, {}, {}}};
  try {
    format_frf_csv(frf);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "'x_A'")) << e.what();
  }
  frf.entries[0].output = "xA";
  frf.set_meta("bad", "two\nlines");
  EXPECT_THROW(format_frf_csv(frf), InputError);
}

TEST(FrfCsv, WriterRefusesInvalidData) {
  FrfData frf;
  frf.freq_hz = {2, 1};
  frf.entries = {FrfEntry{"x", "f", {{1, 2}, {3, 4}}, {}, {}}};
  EXPECT_THROW(format_frf_csv(frf), InputError);
}

// --- accepted variations ----------------------------------------------------

TEST(FrfCsv, ConvertsMicrometreAndMillimetrePerNewtonToMetrePerNewton) {
  const FrfData base = parse_frf_csv(kSmall);
  for (const auto& [unit, scale] : {std::pair{"um/N", 1e-6}, std::pair{"mm/N", 1e-3}}) {
    const FrfData frf = parse_frf_csv(with_line(4, std::string("# unit: ") + unit));
    EXPECT_EQ(frf.unit, "m/N");
    EXPECT_EQ(frf.meta("unit"), "m/N");
    const FrfEntry& e = frf.entries[0];
    EXPECT_DOUBLE_EQ(e.h[1].real(), base.entries[0].h[1].real() * scale);
    EXPECT_DOUBLE_EQ(e.h[1].imag(), base.entries[0].h[1].imag() * scale);
    EXPECT_DOUBLE_EQ(e.sigma[2], base.entries[0].sigma[2] * scale);
    EXPECT_EQ(e.coh[2], base.entries[0].coh[2]);  // coherence has no unit
  }
}

TEST(FrfCsv, KeepsOtherUnitsAsGiven) {
  const FrfData frf = parse_frf_csv(with_line(4, "# unit: (m/s^2)/V"));
  EXPECT_EQ(frf.unit, "(m/s^2)/V");
  EXPECT_EQ(frf.entries[0].h[0].real(), 1e-7);
}

TEST(FrfCsv, DefaultsToComplianceInMetrePerNewton) {
  std::string text = kSmall;
  text.erase(text.find("# quantity"), std::string("# quantity: compliance\n# unit: m/N\n").size());
  const FrfData frf = parse_frf_csv(text);
  EXPECT_EQ(frf.quantity, FrfQuantity::compliance);
  EXPECT_EQ(frf.unit, "m/N");
}

TEST(FrfCsv, AcceptsCrlfBlankLinesAtTheEndAndAMissingFinalNewline) {
  std::string crlf;
  for (char c : kSmall) crlf += (c == '\n') ? std::string("\r\n") : std::string(1, c);
  expect_bit_identical(parse_frf_csv(crlf), parse_frf_csv(kSmall));
  expect_bit_identical(parse_frf_csv(kSmall + "\n\n  \r\n"), parse_frf_csv(kSmall));
  expect_bit_identical(parse_frf_csv(kSmall.substr(0, kSmall.size() - 1)), parse_frf_csv(kSmall));
}

TEST(FrfCsv, AcceptsAnyColumnOrder) {
  const std::string text =
      "# ambdiag.frf/1\n"
      "coh_xAx_fAx,H_xAx_fAx_im,sigma_xAx_fAx,freq_hz,H_xAx_fAx_re\n"
      "0.5,-2,0.1,10,1\n"
      "0.6,-3,0.2,20,2\n";
  const FrfData frf = parse_frf_csv(text);
  ASSERT_EQ(frf.entries.size(), 1u);
  EXPECT_EQ(frf.freq_hz, (std::vector<double>{10, 20}));
  EXPECT_EQ(frf.entries[0].h[1], std::complex<double>(2, -3));
  EXPECT_EQ(frf.entries[0].sigma[0], 0.1);
  EXPECT_EQ(frf.entries[0].coh[1], 0.6);
}

// --- refused files ----------------------------------------------------------

TEST(FrfCsv, RefusesAnEmptyFile) { EXPECT_PRED2(contains, error_of(""), "frf.csv: line 1: empty file"); }

TEST(FrfCsv, RefusesAWrongFirstLine) {
  EXPECT_PRED2(contains, error_of(with_line(1, "# ambdiag.frf/2")), "line 1: the first line must be");
  EXPECT_PRED2(contains, error_of(kSmall.substr(kSmall.find('\n') + 1)), "line 1: the first line must be");
}

TEST(FrfCsv, RefusesAHeaderWithoutDataLines) {
  EXPECT_PRED2(contains, error_of(kSmall.substr(0, kSmall.find("1,1e-7"))),
               "no data lines after the header (line 5)");
}

TEST(FrfCsv, RefusesAFileWithoutHeader) {
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\n# unit: m/N\n"), "no header line");
}

TEST(FrfCsv, RefusesATruncatedFileNamingTheMissingColumn) {
  const std::string cut = kSmall.substr(0, kSmall.size() - 12);  // inside line 8
  EXPECT_PRED2(contains, error_of(cut), "frf.csv: line 8, column ");
  EXPECT_PRED2(contains, error_of(cut), ": missing");
}

TEST(FrfCsv, RefusesANonNumericCellNamingLineAndColumn) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,abc,4e-8,5e-9,2e-9,0.95")),
               "frf.csv: line 7, column H_xAx_fAx_im: not a number 'abc'");
}

TEST(FrfCsv, RefusesNaNAndInfinity) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,NaN,5e-9,2e-9,0.95")),
               "line 7, column H_xAy_fAx_re: NaN or infinity is refused");
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,4e-8,-inf,2e-9,0.95")),
               "line 7, column H_xAy_fAx_im: NaN or infinity is refused");
}

TEST(FrfCsv, RefusesValuesOutOfDoubleRange) {
  EXPECT_PRED2(contains, error_of(with_line(6, "1,1e999,-2e-8,3e-8,4e-9,1e-9,0.9")),
               "line 6, column H_xAx_fAx_re: out of range for a double");
}

TEST(FrfCsv, RefusesAnHEntryWithoutItsImaginaryColumn) {
  EXPECT_PRED2(contains,
               error_of("# ambdiag.frf/1\nfreq_hz,H_xAx_fAx_re,H_xAy_fAx_re,H_xAy_fAx_im\n1,2,3,4\n"),
               "line 2, column H_xAx_fAx_re: no matching _im column");
}

TEST(FrfCsv, RefusesALineWithAnExtraColumn) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,4e-8,5e-9,2e-9,0.95,7")),
               "line 7: more columns than the header's 7");
}

TEST(FrfCsv, RefusesALineWithTooFewColumns) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,4e-8,5e-9")),
               "line 7, column sigma_xAx_fAx: missing (the line has 5 columns, the header 7)");
}

TEST(FrfCsv, RefusesNonIncreasingFrequencyNamingTheLine) {
  EXPECT_PRED2(contains, error_of(with_line(8, "2,3e-7,-4e-8,5e-8,6e-9,3e-9,1")),
               "line 8, column freq_hz: must be strictly increasing (previous line has 2)");
  EXPECT_PRED2(contains, error_of(with_line(8, "1.5,3e-7,-4e-8,5e-8,6e-9,3e-9,1")), "line 8, column freq_hz");
}

TEST(FrfCsv, RefusesZeroFrequency) {
  EXPECT_PRED2(contains, error_of(with_line(6, "0,1e-7,-2e-8,3e-8,4e-9,1e-9,0.9")),
               "line 6, column freq_hz: must be > 0");
}

TEST(FrfCsv, RefusesADuplicateColumn) {
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,H_x_f_re,H_x_f_im,H_x_f_re\n1,2,3,4\n"),
               "line 2, column H_x_f_re: duplicate column");
}

TEST(FrfCsv, RefusesSigmaOrCoherenceWithoutTheirH) {
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,sigma_x_g,H_x_f_re,H_x_f_im\n1,2,3,4\n"),
               "line 2, column sigma_x_g: no H_x_g_re/_im columns for it");
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,H_x_f_re,H_x_f_im,coh_y_f\n1,2,3,0.5\n"),
               "column coh_y_f: no H_y_f_re/_im columns");
}

TEST(FrfCsv, RefusesNegativeSigma) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,4e-8,5e-9,-2e-9,0.95")),
               "line 7, column sigma_xAx_fAx: must be >= 0");
}

TEST(FrfCsv, RefusesCoherenceAboveOne) {
  EXPECT_PRED2(contains, error_of(with_line(7, "2,2e-7,-3e-8,4e-8,5e-9,2e-9,1.0000001")),
               "line 7, column coh_xAx_fAx: must be in 0..1");
}

TEST(FrfCsv, RefusesAnUnknownQuantity) {
  EXPECT_PRED2(contains, error_of(with_line(3, "# quantity: receptance")),
               "line 3: quantity: unknown quantity 'receptance'");
}

TEST(FrfCsv, RefusesABadSpeedAndRepeatedMetadata) {
  EXPECT_PRED2(contains, error_of(with_line(2, "# speed_rpm: fast")), "line 2: speed_rpm: not a number");
  EXPECT_PRED2(contains, error_of(with_line(2, "# unit: m/N")), "line 4: metadata key 'unit' repeated");
  EXPECT_PRED2(contains, error_of(with_line(2, "# just a remark")),
               "line 2: metadata must be '# key: value'");
}

TEST(FrfCsv, RefusesNamesThatDoNotSplitIntoOutputAndInput) {
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,H_x_A_f_re,H_x_A_f_im\n1,2,3\n"),
               "line 2, column H_x_A_f_re: cannot split 'x_A_f' into <output>_<input>");
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,H__f_re,H__f_im\n1,2,3\n"), "cannot split '_f'");
}

TEST(FrfCsv, RefusesUnknownAndEmptyColumns) {
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,H_x_f_re,H_x_f_im,phase_x_f\n1,2,3,4\n"),
               "column phase_x_f: unknown column");
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nfreq_hz,,H_x_f_re,H_x_f_im\n1,2,3,4\n"),
               "line 2, column 2: empty column name");
  EXPECT_PRED2(contains, error_of("# ambdiag.frf/1\nH_x_f_re,H_x_f_im\n2,3\n"), "line 2: no freq_hz column");
}

TEST(FrfCsv, RefusesACarriageReturnInsideALine) {
  EXPECT_PRED2(contains, error_of(with_line(2, "# pump_id: P\r1")),
               "line 2: carriage return inside the line");
}

TEST(FrfCsv, RefusesAnEmptyLineInsideTheData) {
  EXPECT_PRED2(contains, error_of(with_line(7, "")), "line 7: empty line");
}

TEST(FrfCsv, ReadNamesTheFileInEveryError) {
  const auto path = write_scratch("bad.csv", with_line(7, "2,2e-7,x,4e-8,5e-9,2e-9,0.95"));
  try {
    read_frf_csv(path.string());
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_PRED2(contains, e.what(), path.string() + ": line 7, column H_xAx_fAx_im: not a number");
  }
  const std::string missing = (scratch_dir() / "absent.csv").string();
  try {
    read_frf_csv(missing);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_PRED2(contains, e.what(), missing);
  }
}

// --- FrfData ----------------------------------------------------------------

TEST(FrfData, MetaAndSetMetaKeepOrderAndReplaceInPlace) {
  FrfData frf;
  frf.set_meta("a", "1");
  frf.set_meta("b", "2");
  frf.set_meta("a", "3");
  EXPECT_EQ(frf.metadata, (std::vector<std::pair<std::string, std::string>>{{"a", "3"}, {"b", "2"}}));
  EXPECT_EQ(frf.meta("b"), "2");
  EXPECT_FALSE(frf.meta("c").has_value());
}

TEST(FrfData, ValidateRefusesInconsistentData) {
  FrfData frf;
  frf.freq_hz = {1, 2};
  frf.entries = {FrfEntry{"x", "f", {{1, 2}, {3, 4}}, {}, {}}};
  EXPECT_NO_THROW(frf.validate());
  auto refused = [](FrfData d, const std::string& fragment) {
    try {
      d.validate();
      return std::string("<accepted>");
    } catch (const InputError& e) {
      return std::string(e.what()).find(fragment) != std::string::npos ? std::string("ok")
                                                                       : std::string(e.what());
    }
  };
  FrfData d = frf;
  d.entries[0].sigma = {1};
  EXPECT_EQ(refused(d, "sigma has 1 values, freq_hz has 2"), "ok");
  d = frf;
  d.entries.push_back(d.entries[0]);
  EXPECT_EQ(refused(d, "repeated"), "ok");
  d = frf;
  d.entries[0].h[1] = {std::nan(""), 0};
  EXPECT_EQ(refused(d, "h not finite"), "ok");
  d = frf;
  d.freq_hz = {2, 2};
  EXPECT_EQ(refused(d, "freq_hz[1]: must be strictly increasing"), "ok");
  d = frf;
  d.entries[0].coh = {0.5, 1.5};
  EXPECT_EQ(refused(d, "coh must be in 0..1"), "ok");
}

TEST(FrfData, QuantityNames) {
  EXPECT_EQ(to_string(FrfQuantity::compliance), "compliance");
  EXPECT_EQ(to_string(FrfQuantity::mobility), "mobility");
  EXPECT_EQ(to_string(FrfQuantity::accelerance), "accelerance");
}

}  // namespace
}  // namespace ambdiag
