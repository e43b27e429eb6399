// Modal analysis of large rotors by shift-invert block Arnoldi (the Krylov
// solver) against the dense eigen-decomposition on medium models.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/error.h"
#include "generated_rotor.h"
#include "modal_krylov_check.h"

namespace ambdiag {
namespace {

using testing::expect_same_modes;
using testing::rotor_modes;

TEST(ModalKrylov, MatchesDenseOnFortyElementShaftAtSpeed) {
  expect_same_modes(testing::generated_rotor(40), 3000.0, 1500.0);
}

// Every eigenvalue is double for an isotropic rotor at standstill: the block
// of four finds both members of each pair.
TEST(ModalKrylov, FindsRepeatedEigenvaluesOfIsotropicRotorAtStandstill) {
  testing::GeneratedRotorOptions o;
  o.isotropic_bearings = true;
  expect_same_modes(testing::generated_rotor(30, o), 0.0, 1500.0);
}

TEST(ModalKrylov, AutomaticSolverHandlesTwoThousandElements) {
  ModalOptions o;
  o.f_max_hz = 1000.0;
  const ModalResult r = modal_analysis(testing::generated_rotor(2000), 3000.0, o);
  EXPECT_EQ(r.solver, "krylov");
  EXPECT_GT(r.damping_modes_per_plane, 0);
  EXPECT_GE(rotor_modes(r, 1000.0).size(), 4u);
  // The coarse model's modes agree to the discretisation error.
  const ModalResult coarse = modal_analysis(testing::generated_rotor(100), 3000.0, o);
  const auto a = rotor_modes(r, 1000.0), b = rotor_modes(coarse, 1000.0);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i].f_hz, b[i].f_hz, 1e-3 * b[i].f_hz) << i;
}

TEST(ModalKrylov, LargeModelWithoutBandIsRefused) {
  EXPECT_THROW(modal_analysis(testing::generated_rotor(500), 3000.0), InputError);
}

}  // namespace
}  // namespace ambdiag
