// Modal FRF: superposition over the eigenvalues of the first-order form.
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>

#include "ambdiag/core/error.h"
#include "frf_lateral.h"

namespace ambdiag::detail {

Eigen::MatrixXcd lateral_frf_modal(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w) {
  using cd = std::complex<double>;
  const Eigen::Index n = sys.size(), n_out = maps.c_out.rows(), n_in = maps.b_in.cols();
  Eigen::MatrixXcd h(static_cast<Eigen::Index>(w.size()), n_out * n_in);
  if (n_out == 0 || n_in == 0) return h;

  // Balance the state: velocities scaled by a typical frequency, so that the
  // blocks of the first-order matrix have similar norms; this conditions the
  // eigenvectors (a similarity transform, exact in exact arithmetic).
  Eigen::MatrixXd a = first_order_matrix(sys);
  const double s = std::sqrt(a.bottomLeftCorner(n, n).norm() / std::max(1.0, a.topRightCorner(n, n).norm()));
  a.topRightCorner(n, n) *= s;
  a.bottomLeftCorner(n, n) /= s;
  Eigen::EigenSolver<Eigen::MatrixXd> es(a);
  if (es.info() != Eigen::Success) throw InputError("rotor eigenproblem did not converge");
  const Eigen::MatrixXcd v = es.eigenvectors();
  const Eigen::VectorXcd lam = es.eigenvalues();
  Eigen::PartialPivLU<Eigen::MatrixXcd> vlu(v);
  // State input [0; M^-1 B] and output [Cout 0].
  Eigen::MatrixXd bs = Eigen::MatrixXd::Zero(2 * n, n_in);
  bs.bottomRows(n) = Eigen::MatrixXd(sys.m).ldlt().solve(maps.b_in) / s;
  const Eigen::MatrixXcd q = vlu.solve(bs.cast<cd>());           // modes x inputs
  const Eigen::MatrixXcd p = maps.c_out.cast<cd>() * v.topRows(n);  // outputs x modes

  Eigen::MatrixXcd scaled(q.rows(), q.cols());
  for (size_t line = 0; line < w.size(); ++line) {
    const cd jw(0.0, w[line]);
    scaled = (jw - lam.array()).inverse().matrix().asDiagonal() * q;
    const Eigen::MatrixXcd hl = p * scaled;
    for (Eigen::Index o = 0; o < n_out; ++o)
      for (Eigen::Index i = 0; i < n_in; ++i) h(static_cast<Eigen::Index>(line), o * n_in + i) = hl(o, i);
  }
  return h;
}

}  // namespace ambdiag::detail
