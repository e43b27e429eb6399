// Compares the Krylov modal solver with the dense one (shared by the fast
// and the slow modal tests).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "ambdiag/algorithms/model/modal_analysis.h"

namespace ambdiag::testing {

inline std::vector<Mode> rotor_modes(const ModalResult& r, double f_max_hz) {
  std::vector<Mode> out;
  for (const auto& m : r.modes)
    if (m.kind == "rotor" && m.f_hz <= f_max_hz) out.push_back(m);
  return out;
}

// Every mode of one solver below f_max has a partner in the other with f and
// zeta equal to 1e-6 relative, the same whirl, and (shapes) MAC ~ 1.
inline void expect_same_modes(const PlantModel& p, double rpm, double f_max_hz) {
  ModalOptions dense, krylov;
  dense.solver = ModalSolver::dense;
  krylov.solver = ModalSolver::krylov;
  dense.f_max_hz = krylov.f_max_hz = f_max_hz;
  const ModalResult rd = modal_analysis(p, rpm, dense);
  const ModalResult rk = modal_analysis(p, rpm, krylov);
  EXPECT_EQ(rk.solver, "krylov");
  EXPECT_TRUE(rk.converged);
  EXPECT_LT(rk.max_residual, 1e-9);
  const auto md = rotor_modes(rd, f_max_hz), mk = rotor_modes(rk, f_max_hz);
  ASSERT_EQ(mk.size(), md.size());
  ASSERT_GE(md.size(), 6u);
  for (size_t i = 0; i < md.size(); ++i) {
    // Pair by eigenvalue (equal frequencies are whirl pairs at standstill).
    const Mode* best = nullptr;
    for (const auto& m : mk)
      if (!best || std::abs(m.eigenvalue - md[i].eigenvalue) < std::abs(best->eigenvalue - md[i].eigenvalue)) best = &m;
    EXPECT_NEAR(best->f_hz, md[i].f_hz, 1e-6 * md[i].f_hz) << i;
    EXPECT_NEAR(best->zeta, md[i].zeta, 1e-6 * std::abs(md[i].zeta) + 1e-12) << i;
    if (rpm > 0) {
      EXPECT_EQ(best->whirl, md[i].whirl) << i;
    }
    ASSERT_EQ(best->shape.size(), md[i].shape.size());
    if (rpm > 0) {
      const double mac = std::norm(best->shape.dot(md[i].shape)) / (best->shape.squaredNorm() * md[i].shape.squaredNorm());
      EXPECT_GT(mac, 1.0 - 1e-6) << i;
    }
  }
}

}  // namespace ambdiag::testing
