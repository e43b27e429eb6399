// `ambdiag fit` on degenerate FRF files (finite numbers, nothing to fit):
// never a crash; either exit 3 with a message naming the file and what is
// wrong, or exit 0 with no mode and a warning.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_run.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using Result = testing::CliResult;

Result run_fit(const std::string& file) { return testing::run_cli("fit " + file + " --json"); }

// One SISO compliance file; `h(f)` gives the value, `sigma(f)` < 0 omits
// the sigma column.
template <class H, class S>
std::string frf_file(const std::string& name, int lines, H h, S sigma) {
  std::ostringstream s;
  s.precision(17);
  const bool with_sigma = sigma(1.0) >= 0;
  s << "# ambdiag.frf/1\n# quantity: compliance\n# unit: m/N\nfreq_hz,H_x1_f1_re,H_x1_f1_im" << (with_sigma ? ",sigma_x1_f1" : "") << "\n";
  for (int l = 1; l <= lines; ++l) {
    const double f = l;
    const std::complex<double> v = h(f);
    s << f << "," << v.real() << "," << v.imag();
    if (with_sigma) s << "," << sigma(f);
    s << "\n";
  }
  return testing::write_scratch(name, s.str()).string();
}

void expect_refused(const Result& r, const std::string& file, const std::string& what) {
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
}

TEST(CliFitBadFrf, AllZerosIsRefusedNamingTheFile) {
  const auto zero = [](double) { return std::complex<double>(0.0, 0.0); };
  const std::string with = frf_file("zeros_sigma.csv", 200, zero, [](double) { return 1e-9; });
  expect_refused(run_fit(with), "zeros_sigma.csv", "noise");
  const std::string without = frf_file("zeros.csv", 200, zero, [](double) { return -1.0; });
  expect_refused(run_fit(without), "zeros.csv", "noise");
}

TEST(CliFitBadFrf, TooFewLinesAreRefused) {
  const auto one = [](double) { return std::complex<double>(1e-6, 0.0); };
  expect_refused(run_fit(frf_file("one_line.csv", 1, one, [](double) { return 1e-8; })), "one_line.csv", "lines");
}

TEST(CliFitBadFrf, ZeroSigmaIsRefusedNamingTheEntry) {
  const auto h = [](double f) { return 1.0 / std::complex<double>(1e4 - f * f, 10.0 * f); };
  expect_refused(run_fit(frf_file("sigma0.csv", 200, h, [](double) { return 0.0; })), "sigma0.csv", "sigma of x1/f1");
}

// Noise only: with sigma, the entry does not rise above its noise (refused);
// without sigma, nothing is significant against the residual: 0 modes and a
// warning, exit 0.
TEST(CliFitBadFrf, PureNoiseGivesNoModes) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 1e-8);
  const auto noise = [&](double) { return std::complex<double>(n(rng), n(rng)); };
  expect_refused(run_fit(frf_file("noise_sigma.csv", 500, noise, [](double) { return 1.41e-8; })), "noise_sigma.csv", "noise");
  const Result r = run_fit(frf_file("noise.csv", 500, noise, [](double) { return -1.0; }));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["modes"].size(), 0u) << r.out;
  EXPECT_NE(r.err.find("warning"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("noise.csv"), std::string::npos) << r.err;
}

// Without sigma columns the fit still works: the residual sets the noise.
TEST(CliFitBadFrf, MissingSigmaStillFindsAClearMode) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1e-7);
  const double w0 = 2 * M_PI * 120.0, z0 = 0.02;
  const auto h = [&](double f) {
    const double w = 2 * M_PI * f;
    return 1.0 / std::complex<double>(w0 * w0 - w * w, 2 * z0 * w0 * w) + std::complex<double>(n(rng), n(rng));
  };
  const Result r = run_fit(frf_file("nosigma.csv", 400, h, [](double) { return -1.0; }));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["modes"].size(), 1u) << r.out;
  EXPECT_NEAR(j["modes"][0]["f_hz"].get<double>(), 120.0, 0.5);
  EXPECT_FALSE(j["fit"]["sigma_from_data"].get<bool>());
}

}  // namespace
}  // namespace ambdiag
