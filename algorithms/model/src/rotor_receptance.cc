#include "ambdiag/algorithms/model/rotor_receptance.h"

#include "frf_pole_sum.h"

namespace ambdiag::detail {

RotorReceptance::RotorReceptance(const RotorSystem& sys, const std::vector<double>& omega_rad_per_s)
    : sys_(sys), f_(modal_factors(sys)), jw_(static_cast<Eigen::Index>(omega_rad_per_s.size())) {
  for (Eigen::Index l = 0; l < jw_.size(); ++l) jw_(l) = {0.0, omega_rad_per_s[static_cast<size_t>(l)]};
}

Eigen::MatrixXcd RotorReceptance::block(const std::vector<int>& rows, const std::vector<int>& cols) const {
  const Eigen::Index m = f_.eigenvalues.size();
  Eigen::MatrixXd left(static_cast<Eigen::Index>(rows.size()), m), right(m, static_cast<Eigen::Index>(cols.size()));
  for (size_t r = 0; r < rows.size(); ++r) left.row(static_cast<Eigen::Index>(r)) = sys_.dof_row(rows[r]) * f_.top;
  for (size_t c = 0; c < cols.size(); ++c) right.col(static_cast<Eigen::Index>(c)) = f_.right * sys_.dof_row(cols[c]).transpose();
  if (rows.empty() || cols.empty()) return Eigen::MatrixXcd(jw_.size(), left.rows() * right.cols());
  return PoleSum(f_.eigenvalues, left, right).evaluate(jw_, Eigen::VectorXcd::Ones(jw_.size()));
}

}  // namespace ambdiag::detail
