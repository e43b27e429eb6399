// The modal fit kept as fit_model.json (server/src/analysis/fit_model_file.h):
// written from a real fit and read back through its text, it gives the
// fit's own values on the grid (and so the curve the modes come from);
// the quantity's power of jw is put back; a broken document is refused
// naming the key.
#include "analysis/fit_model_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>

#include "ambdiag/core/error.h"
#include "test_support.h"

namespace ambdiag::server::detail {
namespace {

using cd = std::complex<double>;
using nlohmann::json;

// Through the text, as the historian keeps it.
FrfData round_trip(const RationalFitResult& fit, const FrfData& frf) {
  return fit_frf_like(json::parse(fit_model_json(fit, frf).dump()), frf);
}

TEST(FitModelFile, ReproducesTheFittedModelOnTheGridAndFollowsTheMeasurement) {
  const FrfData frf = read_frf_csv(ambdiag::testing::data_file("ident_7mode/frf.csv").string());
  const RationalFitResult fit = fit_rational(frf);
  const FrfData out = round_trip(fit, frf);
  ASSERT_EQ(out.entries.size(), fit.entries.size());
  EXPECT_EQ(out.freq_hz, frf.freq_hz);
  double err2 = 0, meas2 = 0;
  for (size_t e = 0; e < out.entries.size(); ++e) {
    const FrfEntry& measured = frf.entries[static_cast<size_t>(fit.entries[e])];
    EXPECT_EQ(out.entries[e].output, measured.output);
    EXPECT_EQ(out.entries[e].input, measured.input);
    for (size_t l = 0; l < frf.freq_hz.size(); ++l) {
      const cd in_memory = fit.model.evaluate(static_cast<int>(e), 2 * M_PI * frf.freq_hz[l]);
      ASSERT_LE(std::abs(out.entries[e].h[l] - in_memory), 1e-12 * std::abs(in_memory)) << e << " " << l;
      err2 += std::norm(out.entries[e].h[l] - measured.h[l]);
      meas2 += std::norm(measured.h[l]);
    }
  }
  // The fit follows the measurement to its noise (chi2/dof about 1): a
  // few per cent of its RMS, not a curve of another shape.
  EXPECT_LT(std::sqrt(err2 / meas2), 0.05);
}

// A mobility is fitted as mobility / (jw): the file says so and the curve
// comes back as mobility, with the delay.
TEST(FitModelFile, PutsBackThePowerOfJwAndTheDelay) {
  FrfData grid;
  grid.quantity = FrfQuantity::mobility;
  grid.unit = "m/s/N";
  grid.freq_hz = {10, 50, 95, 100, 105, 300};
  grid.entries.push_back({"x", "f", std::vector<cd>(6), {}, {}});
  RationalFitResult fit;
  fit.numerator_power = 1;
  fit.entries = {0};
  const cd pole(-12.0, 2 * M_PI * 100), r(1e-4, -3e-3);
  fit.model.poles = {pole, cd(-500.0, 0.0)};
  fit.model.residues.resize(1, 2);
  fit.model.residues << r, cd(2e-2, 0.0);
  fit.model.direct.resize(1);
  fit.model.direct << 1e-7;
  fit.model.delay_s = 1e-4;
  const FrfData out = round_trip(fit, grid);
  ASSERT_EQ(out.entries.size(), 1u);
  EXPECT_EQ(out.quantity, FrfQuantity::mobility);
  for (size_t l = 0; l < grid.freq_hz.size(); ++l) {
    const cd s(0.0, 2 * M_PI * grid.freq_hz[l]);
    const cd expected =
        s * std::exp(-s * 1e-4) * (1e-7 + r / (s - pole) + std::conj(r) / (s - std::conj(pole)) + 2e-2 / (s + 500.0));
    EXPECT_LE(std::abs(out.entries[0].h[l] - expected), 1e-12 * std::abs(expected)) << grid.freq_hz[l];
  }
}

TEST(FitModelFile, RefusesABrokenDocumentNamingTheKey) {
  FrfData grid;
  grid.freq_hz = {10, 20};
  RationalFitResult fit;
  fit.entries = {0};
  grid.entries.push_back({"x", "f", std::vector<cd>(2), {}, {}});
  fit.model.poles = {cd(-1.0, 60.0)};
  fit.model.residues = Eigen::MatrixXcd::Constant(1, 1, cd(1.0, 0.0));
  fit.model.direct = Eigen::VectorXd::Zero(1);
  const json good = fit_model_json(fit, grid);
  const auto refused = [&](const std::function<void(json&)>& change, const std::string& named) {
    json doc = good;
    change(doc);
    try {
      fit_frf_like(doc, grid);
      ADD_FAILURE() << "accepted: " << doc.dump();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << e.what();
    }
  };
  refused([](json& d) { d["format"] = "other/1"; }, "format");
  refused([](json& d) { d.erase("entries"); }, "entries");
  refused([](json& d) { d["numerator_power"] = 3; }, "numerator_power");
  refused([](json& d) { d["poles_rad_per_s"][0] = json::array({1.0}); }, "poles_rad_per_s[0]");
  refused([](json& d) { d["entries"][0]["residues"].push_back(json::array({1.0, 0.0})); }, "entries[0].residues");
  refused([](json& d) { d["entries"][0]["direct"] = "x"; }, "entries[0].direct");
  refused([](json& d) { d["delay_s"] = nullptr; }, "delay_s");
  refused([](json& d) { d["entries"].push_back(d["entries"][0]); }, "repeated");
  EXPECT_NO_THROW(fit_frf_like(good, grid));
}

}  // namespace
}  // namespace ambdiag::server::detail
