// The FRF paths for speed and size against the exact ones: a band of
// structurally damped modes against all of them, and the Krylov modal FRF
// against the direct solve.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "generated_rotor.h"
#include "test_support.h"

namespace ambdiag {
namespace {

std::string scientific(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3e", x);
  return buf;
}

// Largest over entries of the rms difference relative to the rms of `ref`.
double worst_relative_rms(const FrfData& a, const FrfData& ref) {
  double worst = 0.0;
  for (size_t k = 0; k < ref.entries.size(); ++k) {
    double num = 0, den = 0;
    for (size_t l = 0; l < ref.freq_hz.size(); ++l) {
      num += std::norm(a.entries[k].h[l] - ref.entries[k].h[l]);
      den += std::norm(ref.entries[k].h[l]);
    }
    if (den > 0) worst = std::max(worst, std::sqrt(num / den));
  }
  return worst;
}

// Largest difference on any line relative to the largest |H| of its entry.
double worst_relative_peak(const FrfData& a, const FrfData& ref) {
  double worst = 0.0;
  for (size_t k = 0; k < ref.entries.size(); ++k) {
    double peak = 0, diff = 0;
    for (size_t l = 0; l < ref.freq_hz.size(); ++l) {
      peak = std::max(peak, std::abs(ref.entries[k].h[l]));
      diff = std::max(diff, std::abs(a.entries[k].h[l] - ref.entries[k].h[l]));
    }
    if (peak > 0) worst = std::max(worst, diff / peak);
  }
  return worst;
}

// Dropping the damping of free-free modes above 10 x f_max changes each such
// mode's response by at most 2 zeta / 10 = 1.5e-3 (rotor_system.h); the
// FRF moves by that times their share, well below it.
TEST(FrfFastPaths, BandOfDampedModesStaysWithinItsBoundOnReferencePump) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const std::vector<double> f = frequency_grid(1.0, 1000.0, 3.0);
  FrfSynthesisOptions all, band;
  all.damping.modes = StructuralDampingOptions::Modes::all;
  band.damping.modes = StructuralDampingOptions::Modes::band;
  FrfReport rep_all, rep_band;
  const FrfData exact = synthesize_frf(plant, 2950, f, all, &rep_all);
  const FrfData cut = synthesize_frf(plant, 2950, f, band, &rep_band);
  EXPECT_EQ(rep_all.damping_modes_per_plane, 42);
  EXPECT_LT(rep_band.damping_modes_per_plane, 42);
  EXPECT_NEAR(rep_band.damping_cutoff_hz, 10000.0, 1e-6);
  const double bound = 2.0 * plant.structural_damping.zeta / band.damping.band_factor;
  const double err = worst_relative_rms(cut, exact);
  EXPECT_LT(err, bound);
  RecordProperty("relative_rms_error", scientific(err));
  RecordProperty("damped_modes_per_plane", std::to_string(rep_band.damping_modes_per_plane));
}

TEST(FrfFastPaths, KrylovModalMatchesDirectOnReferencePump) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const std::vector<double> f = frequency_grid(1.0, 1000.0, 3.0);
  FrfSynthesisOptions krylov;
  krylov.method = FrfMethod::modal;
  krylov.modal_basis = ModalBasis::krylov;
  FrfReport rep;
  const FrfData direct = synthesize_frf(plant, 2950, f);
  const FrfData modal = synthesize_frf(plant, 2950, f, krylov, &rep);
  EXPECT_TRUE(rep.converged);
  EXPECT_LT(rep.krylov_residual, krylov.krylov_tol);
  EXPECT_LT(worst_relative_rms(modal, direct), 1e-7);
  EXPECT_LT(worst_relative_peak(modal, direct), 1e-7);
  RecordProperty("krylov_size", std::to_string(rep.krylov_size));
  RecordProperty("relative_rms_error", scientific(worst_relative_rms(modal, direct)));
}

TEST(FrfFastPaths, KrylovModalMatchesDirectOnSixtyElementShaft) {
  const PlantModel plant = testing::generated_rotor(60);
  const std::vector<double> f = frequency_grid(2.0, 2000.0, 8.0);
  FrfSynthesisOptions direct, krylov;
  direct.damping.modes = krylov.damping.modes = StructuralDampingOptions::Modes::band;
  krylov.method = FrfMethod::modal;
  krylov.modal_basis = ModalBasis::krylov;
  FrfReport rd, rk;
  const FrfData hd = synthesize_frf(plant, 3000, f, direct, &rd);
  const FrfData hk = synthesize_frf(plant, 3000, f, krylov, &rk);
  EXPECT_NE(rd.method.find("Woodbury"), std::string::npos) << rd.method;
  EXPECT_TRUE(rk.converged);
  EXPECT_LT(worst_relative_rms(hk, hd), 1e-7);
  EXPECT_LT(worst_relative_peak(hk, hd), 1e-7);
}

// The default modal basis is the Krylov one for the pump too; the sum over
// every eigenvalue (dense eigen-decomposition, real-arithmetic pole sum) stays
// as the exact reference. Its bound is the round-off of the 176-state
// eigen-decomposition (frf_synthesis_test.cc).
TEST(FrfFastPaths, AutomaticModalBasisIsKrylovAndAllEigenvaluesAgreeOnReferencePump) {
  const PlantModel plant = read_plant_file(testing::data_file("reference_pump/plant.json"));
  const std::vector<double> f = frequency_grid(1.0, 1000.0, 3.0);
  FrfSynthesisOptions automatic, all;
  automatic.method = all.method = FrfMethod::modal;
  all.modal_basis = ModalBasis::all;
  FrfReport ra, rall;
  const FrfData direct = synthesize_frf(plant, 2950, f);
  const FrfData ha = synthesize_frf(plant, 2950, f, automatic, &ra);
  const FrfData hall = synthesize_frf(plant, 2950, f, all, &rall);
  EXPECT_NE(ra.method.find("Krylov"), std::string::npos) << ra.method;
  EXPECT_TRUE(ra.converged);
  EXPECT_LT(worst_relative_rms(ha, direct), 1e-7);
  EXPECT_NE(rall.method.find("all eigenvalues"), std::string::npos) << rall.method;
  EXPECT_EQ(rall.poles, 176);
  EXPECT_LT(worst_relative_rms(hall, direct), 1e-6);
  EXPECT_LT(worst_relative_peak(hall, direct), 1e-6);
}

// A rotor so small (10 elements, 88 states) and a band so wide (5 kHz) that
// the Krylov basis fills the state space before it reaches krylov_tol: the
// automatic basis must then fall back to every eigenvalue and still match
// the direct FRF.
TEST(FrfFastPaths, AutomaticModalMatchesDirectOnTenElementShaft) {
  const PlantModel plant = testing::generated_rotor(10);
  const std::vector<double> f = frequency_grid(5.0, 5000.0, 5.0);
  FrfSynthesisOptions modal;
  modal.method = FrfMethod::modal;
  FrfReport rep;
  const FrfData hd = synthesize_frf(plant, 3000, f);
  const FrfData hm = synthesize_frf(plant, 3000, f, modal, &rep);
  EXPECT_TRUE(rep.converged);
  EXPECT_LT(worst_relative_rms(hm, hd), 1e-7);
  EXPECT_LT(worst_relative_peak(hm, hd), 1e-7);
  RecordProperty("method", rep.method);
  RecordProperty("poles", std::to_string(rep.poles));
}

}  // namespace
}  // namespace ambdiag
