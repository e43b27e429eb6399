// Shared by the rational-fit tests: the noise-free ident_7mode system of
// ../shared/data/ident_7mode/truth.json, fresh noise realisations, and the
// RMSE / Cramer-Rao comparison.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>

#include <nlohmann/json.hpp>

#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/core/frf_data.h"
#include "test_support.h"

namespace ambdiag::seven_mode {

using nlohmann::json;
using cd = std::complex<double>;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

inline json load_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

// The noise-free ident_7mode system from its truth.json, plus fresh noise.
struct SevenMode {
  std::vector<cd> poles, residues;
  std::vector<double> freq_hz;
  double sigma = 0.0;
  json crlb;

  SevenMode() {
    const json t = load_json(testing::data_file("ident_7mode/truth.json"));
    for (const auto& p : t["poles_rad_s"]) poles.emplace_back(p[0].get<double>(), p[1].get<double>());
    for (const auto& r : t["residues_pole_residue_form"]) residues.emplace_back(r[0].get<double>(), r[1].get<double>());
    sigma = t["noise"]["sigma"].get<double>();
    crlb = t["crlb"]["per_mode"];
    freq_hz = read_frf_csv(testing::data_file("ident_7mode/frf.csv").string()).freq_hz;
  }
  FrfData realisation(std::mt19937_64& rng) const {
    std::normal_distribution<double> n(0.0, sigma / std::sqrt(2.0));
    FrfData f;
    f.freq_hz = freq_hz;
    FrfEntry e{"x1", "f1", {}, {}, {}};
    for (double fh : freq_hz) {
      const cd s(0.0, kTwoPi * fh);
      cd h = 0.0;
      for (size_t k = 0; k < poles.size(); ++k) h += residues[k] / (s - poles[k]) + std::conj(residues[k]) / (s - std::conj(poles[k]));
      e.h.push_back(h + cd(n(rng), n(rng)));
      e.sigma.push_back(sigma);
    }
    f.entries.push_back(e);
    return f;
  }
};

// Root-mean-square error over noise realisations divided by the Cramer-Rao
// bound of truth.json, per mode: an efficient estimator gives about 1.
inline void expect_near_cramer_rao(int realisations, double max_ratio, bool auto_order) {
  const SevenMode sys;
  std::mt19937_64 rng(20261122);
  const size_t m = sys.poles.size();
  std::vector<double> se_f(m, 0.0), se_z(m, 0.0);
  for (int r = 0; r < realisations; ++r) {
    RationalFitOptions opt;
    opt.modes = auto_order ? 0 : 7;
    const RationalFitResult fit = fit_rational(sys.realisation(rng), opt);
    ASSERT_EQ(fit.modes.size(), m) << "realisation " << r;
    for (size_t k = 0; k < m; ++k) {
      const double f0 = sys.crlb[k]["fn_hz"].get<double>(), z0 = sys.crlb[k]["zeta"].get<double>();
      se_f[k] += std::pow(fit.modes[k].f_hz - f0, 2);
      se_z[k] += std::pow(fit.modes[k].zeta - z0, 2);
    }
  }
  for (size_t k = 0; k < m; ++k) {
    const double rf = std::sqrt(se_f[k] / realisations) / sys.crlb[k]["fn_std_hz"].get<double>();
    const double rz = std::sqrt(se_z[k] / realisations) / sys.crlb[k]["zeta_std"].get<double>();
    EXPECT_LT(rf, max_ratio) << "mode " << k << " f RMSE/CRLB";
    EXPECT_LT(rz, max_ratio) << "mode " << k << " zeta RMSE/CRLB";
    std::printf("mode %zu (%.0f Hz): RMSE/CRLB f %.2f zeta %.2f\n", k, sys.crlb[k]["fn_hz"].get<double>(), rf, rz);
  }
}

}  // namespace ambdiag::seven_mode
