// Every shared FRF with a truth: the reference pump's five measurements, the
// faults, the explain cases (an acquisition delay, cross coupling, the
// paper's Table 3 pump with extra axial and housing modes) and ident_7mode.
// Prints the accuracy table of docs/fit.md.
#include <filesystem>
#include <numbers>
#include <random>

#include "truth_modes.h"

namespace ambdiag {
namespace {

TEST(RationalFitSlow, EveryTruthModeOfEverySharedFrfWithinHalfPercentAndTenPercentDampingWhereTheNoiseAllows) {
  std::vector<std::string> cases;
  for (int i = 1; i <= 5; ++i) cases.push_back("reference_pump/frf_ref_" + std::to_string(i) + ".csv");
  std::vector<std::string> dirs;
  for (const auto& d : std::filesystem::directory_iterator(testing::shared_data())) {
    const std::string name = d.path().filename().string();
    if ((name.rfind("fault_", 0) == 0 || name.rfind("explain_", 0) == 0) && std::filesystem::exists(d.path() / "truth.json"))
      dirs.push_back(name);
  }
  std::sort(dirs.begin(), dirs.end());
  ASSERT_GE(dirs.size(), 7u);
  std::printf("| file | mode | f truth (Hz) | zeta truth | f err (%%) | zeta err (%%) | zeta sd (%%) | zeta tol (%%) | |\n"
      "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (int i = 1; i <= 5; ++i) truth_modes::expect_truth_modes_identified(cases[static_cast<size_t>(i - 1)], "reference_pump/truth.json");
  for (const auto& d : dirs) truth_modes::expect_truth_modes_identified(d + "/frf.csv", d + "/truth.json");
  truth_modes::expect_truth_modes_identified("ident_7mode/frf.csv", "ident_7mode/truth.json");
}

// explain_paper_table3's weak bending-3 forward mode (872.5 Hz, 3 % above
// its backward partner, 4 % below a repeated housing root, every entry at
// most 4 sigma) comes out with a damping 13 % above the truth, 0.7 of its
// reported sd. Is that sd right? Parametric bootstrap: complex Gaussian
// noise of the file's sigma added to the fitted model, refitted; the spread
// of the mode's zeta over the refits must agree with the reported sd (20
// realisations: the spread itself scatters by 1/sqrt(2 (n - 1)) = 16-18 %,
// so 0.6-1.6 is about 3 of its standard deviations).
TEST(RationalFitSlow, Table3WeakForwardModeReportedDampingSdMatchesTheSpreadOverRefits) {
  const FrfData frf = read_frf_csv(testing::data_file("explain_paper_table3/frf.csv").string());
  const RationalFitResult fit = fit_rational(frf);
  auto nearest = [](const RationalFitResult& r, double f0) {
    const IdentifiedMode* best = nullptr;
    for (const auto& m : r.modes)
      if (!best || std::abs(m.f_hz - f0) < std::abs(best->f_hz - f0)) best = &m;
    return best;
  };
  const IdentifiedMode* mode = nearest(fit, 872.5);
  ASSERT_NE(mode, nullptr);
  ASSERT_EQ(fit.numerator_power, 0);  // compliance: the model is the FRF itself
  std::mt19937_64 rng(872);
  std::normal_distribution<double> normal(0.0, std::sqrt(0.5));
  std::vector<double> zeta, f;
  const int n = 20;
  for (int i = 0; i < n; ++i) {
    FrfData g = frf;
    for (size_t k = 0; k < fit.entries.size(); ++k) {
      FrfEntry& en = g.entries[static_cast<size_t>(fit.entries[k])];
      for (size_t l = 0; l < g.freq_hz.size(); ++l)
        en.h[l] = fit.model.evaluate(static_cast<int>(k), 2.0 * std::numbers::pi * g.freq_hz[l]) +
                  en.sigma[l] * std::complex<double>(normal(rng), normal(rng));
    }
    const RationalFitResult r = fit_rational(g);
    const IdentifiedMode* m = nearest(r, mode->f_hz);
    if (!m || std::abs(m->f_hz - mode->f_hz) > 0.01 * mode->f_hz) continue;  // merged: counted as missing
    zeta.push_back(m->zeta);
    f.push_back(m->f_hz);
  }
  auto mean_sd = [](const std::vector<double>& v) {
    double m = 0.0, q = 0.0;
    for (double x : v) m += x / static_cast<double>(v.size());
    for (double x : v) q += (x - m) * (x - m) / static_cast<double>(v.size() - 1);
    return std::pair<double, double>(m, std::sqrt(q));
  };
  // The mode is at the edge of detection: found (within 1 %) in 16 of
  // these 20 refits; the others merge it with a neighbour.
  ASSERT_GE(zeta.size(), static_cast<size_t>(n / 2));
  const auto [zm, zs] = mean_sd(zeta);
  const auto [fm, fs] = mean_sd(f);
  std::printf("872 Hz mode: fit f %.2f Hz (sd %.2f) zeta %.5f (sd %.5f); found in %zu of %d refits: f %.2f +- %.2f Hz, zeta %.5f +- %.5f "
              "(spread / reported sd: f %.2f, zeta %.2f; bias of zeta %.2f sd)\n",
              mode->f_hz, mode->f_sd_hz, mode->zeta, mode->zeta_sd, zeta.size(), n, fm, fs, zm, zs, fs / mode->f_sd_hz, zs / mode->zeta_sd,
              (zm - mode->zeta) / zs);
  EXPECT_GT(zs / mode->zeta_sd, 0.6);
  EXPECT_LT(zs / mode->zeta_sd, 1.6);
  EXPECT_GT(fs / mode->f_sd_hz, 0.6);
  EXPECT_LT(fs / mode->f_sd_hz, 1.6);
}

}  // namespace
}  // namespace ambdiag
