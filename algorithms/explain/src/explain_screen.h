// Screening of rotor candidates for explain (explain_select.cc) without FE
// solves. A candidate that changes the lateral system only on a few DOFs U
// (an added mass at a node, a link's coefficients, disks' Ip) changes the
// dynamic stiffness by dZ(w) = dK - w^2 dM + j w dC on U, linear in its
// parameters, and moves no or some sensors. With the current rotor's
// receptance G (rotor_receptance.h) the new FRF follows exactly by Woodbury:
//
//   H'[s, a] = G[s', a] - G[s', U] (I + dZ G[U, U])^-1 dZ G[U, a]
//
// (s' the sensor's DOF after the change), so a candidate's parameters can be
// fitted on this cheap model and only the best few fitted on the real one.
// Not modelled: the change of the modal structural damping C_s that a mass
// change brings (second order); candidates whose change shows in no node
// matrix (structural damping itself) get no model. Private to explain.
#pragma once

#include <complex>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "ambdiag/algorithms/model/rotor_receptance.h"

namespace ambdiag::detail {

// One candidate's change on the current rotor.
struct LowRankChange {
  std::vector<int> dofs;                            // U
  std::vector<Eigen::MatrixXd> dk, dm, dc;          // [0]: at the neutral point; [1 + i]: per unit scaled step of parameter i
  std::vector<int> sensor_row;                      // per measured entry: row of the block for its (moved) sensor, -1: not lateral
  std::vector<int> actuator_col;                    // per measured entry
  Eigen::MatrixXcd g_sa, g_su, g_uu, g_ua;          // lines x flattened blocks
  int n_rows = 0, n_cols = 0;                       // distinct sensor / actuator DOFs in the blocks
};

class RotorScreen {
 public:
  // The receptance of `current` on every measured line (one eigen-decomposition).
  RotorScreen(const PlantVariant& current, PlantFrfEvaluator& eval);

  // nullopt: the candidate changes no node matrix and no sensor, or more than
  // 24 DOFs; use finite differences.
  std::optional<LowRankChange> change_of(const Candidate& c) const;

  // Change of the weighted residual (entry-major over `lines`, like
  // PlantFrfEvaluator::residual) when c takes values x.
  std::vector<std::complex<double>> residual_change(const LowRankChange& ch, const Candidate& c, const std::vector<double>& x,
                                                    const std::vector<int>& lines) const;
  // The weighted residual with c at x: `base` (the current rotor's residual
  // on the same lines) plus residual_change.
  std::vector<std::complex<double>> residual_with(const LowRankChange& ch, const Candidate& c, const std::vector<double>& x,
                                                  const std::vector<int>& lines, const std::vector<std::complex<double>>& base) const;

 private:
  PlantVariant current_;
  PlantFrfEvaluator& eval_;
  std::vector<double> omega_;
  std::unique_ptr<RotorReceptance> g_;
  std::vector<int> base_sensor_dof_, base_actuator_dof_;  // per measured entry, -1: not lateral
  std::vector<int> base_index_;                            // per measured entry: column of base_, -1: not lateral
  Eigen::MatrixXcd base_;                                  // (sensor DOFs x actuator DOFs) x lines: G[s, a] now
  // Shared blocks: G[every DOF, actuator DOFs], G[sensor DOFs, every DOF],
  // and G[U, U] per DOF set.
  std::vector<int> sensor_dofs_, actuator_dofs_;
  Eigen::MatrixXcd col_a_, row_s_;
  mutable std::map<std::vector<int>, Eigen::MatrixXcd> uu_;
  std::optional<LowRankChange> impedance_change(const Candidate& c) const;
  void finish_change(LowRankChange& ch, const std::vector<int>& sensors) const;
  // Block G[rows, cols] from the shared ones where they hold it.
  Eigen::MatrixXcd block(const std::vector<int>& rows, const std::vector<int>& cols) const;
};

}  // namespace ambdiag::detail
