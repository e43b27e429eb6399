// Free-free plane modes: the Lanczos solver for large rotors against the
// dense generalized eigenproblem.
#include <gtest/gtest.h>

#include <cmath>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "generated_rotor.h"

namespace ambdiag {
namespace {

// |a^T M b|^2 / ((a^T M a)(b^T M b)) with M-normalised shapes reduces to
// (a . M b)^2; here plain MAC on the shapes, enough to tell modes apart.
double mac(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const double ab = a.dot(b);
  return ab * ab / (a.squaredNorm() * b.squaredNorm());
}

TEST(PlaneModes, LanczosMatchesDenseOnHundredElementShaft) {
  const PlantModel p = testing::generated_rotor(100);
  PlaneModeOptions dense_opt, lanczos_opt;
  dense_opt.solver = PlaneModeOptions::Solver::dense;
  lanczos_opt.solver = PlaneModeOptions::Solver::lanczos;
  lanczos_opt.omega_max_rad_per_s = dense_opt.omega_max_rad_per_s = 2.0 * M_PI * 20000.0;
  const PlaneModes d = free_free_plane_modes(p, dense_opt);
  const PlaneModes l = free_free_plane_modes(p, lanczos_opt);
  EXPECT_EQ(l.solver, "lanczos");
  EXPECT_TRUE(l.sturm_checked);
  ASSERT_EQ(l.omega_rad_per_s.size(), d.omega_rad_per_s.size());
  ASSERT_GE(l.omega_rad_per_s.size(), 8);
  for (Eigen::Index i = 2; i < l.omega_rad_per_s.size(); ++i) {
    EXPECT_NEAR(l.omega_rad_per_s(i), d.omega_rad_per_s(i), 1e-9 * d.omega_rad_per_s(i)) << "mode " << i;
    EXPECT_GT(mac(l.shapes.col(i), d.shapes.col(i)), 1.0 - 1e-9) << "mode " << i;
  }
  // Rigid-body modes: same two-dimensional space (projector onto it).
  const Eigen::MatrixXd pl = l.shapes.leftCols(2) * l.shapes.leftCols(2).transpose();
  const Eigen::MatrixXd pd = d.shapes.leftCols(2) * d.shapes.leftCols(2).transpose();
  EXPECT_LT((pl - pd).norm(), 1e-8 * pd.norm());
  EXPECT_EQ(l.omega_rad_per_s(0), 0.0);
  EXPECT_EQ(l.omega_rad_per_s(1), 0.0);
}

TEST(PlaneModes, LanczosReturnsTheFirstCountModesOfALargeShaft) {
  const PlantModel p = testing::generated_rotor(1000);
  PlaneModeOptions o;
  o.max_elastic = 12;
  const PlaneModes l = free_free_plane_modes(p, o);
  EXPECT_EQ(l.solver, "lanczos");
  EXPECT_TRUE(l.sturm_checked);
  ASSERT_EQ(l.omega_rad_per_s.size(), 14);
  for (Eigen::Index i = 3; i < 14; ++i) EXPECT_GT(l.omega_rad_per_s(i), l.omega_rad_per_s(i - 1));
  // The same rotor in 100 elements: the lowest frequencies agree to the
  // discretisation error (Timoshenko elements converge fast).
  PlaneModeOptions od;
  od.max_elastic = 4;
  const PlaneModes coarse = free_free_plane_modes(testing::generated_rotor(100), od);
  for (Eigen::Index i = 2; i < 6; ++i) EXPECT_NEAR(l.omega_rad_per_s(i), coarse.omega_rad_per_s(i), 1e-4 * l.omega_rad_per_s(i));
}

TEST(PlaneModes, CountKeepsTheRigidBodyModesFirst) {
  const PlantModel p = testing::generated_rotor(20);
  const PlaneModes m = free_free_plane_modes(p, 5);
  ASSERT_EQ(m.omega_rad_per_s.size(), 5);
  EXPECT_EQ(m.omega_rad_per_s(0), 0.0);
  EXPECT_EQ(m.omega_rad_per_s(1), 0.0);
  EXPECT_GT(m.omega_rad_per_s(2), 0.0);
}

}  // namespace
}  // namespace ambdiag
