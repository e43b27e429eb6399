// Modal FRF: superposition over every eigenvalue of the first-order form.
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>

#include "ambdiag/algorithms/model/rotor_receptance.h"
#include "ambdiag/core/error.h"
#include "frf_lateral.h"
#include "frf_pole_sum.h"

namespace ambdiag::detail {

ModalFactors modal_factors(const RotorSystem& sys) {
  const Eigen::Index n = sys.size();
  // Balance the state: velocities scaled by a typical frequency, so that the
  // blocks of the first-order matrix have similar norms; this conditions the
  // eigenvectors (a similarity transform, exact in exact arithmetic).
  Eigen::MatrixXd a = first_order_matrix(sys);
  const double s = std::sqrt(a.bottomLeftCorner(n, n).norm() / std::max(1.0, a.topRightCorner(n, n).norm()));
  a.topRightCorner(n, n) *= s;
  a.bottomLeftCorner(n, n) /= s;
  Eigen::EigenSolver<Eigen::MatrixXd> es(a);
  if (es.info() != Eigen::Success) throw InputError("rotor eigenproblem did not converge");
  ModalFactors f;
  f.eigenvalues = es.eigenvalues();
  // The real pseudo-eigenvector matrix P (A P = P D, D with 2 x 2 blocks for
  // complex pairs) spans the same modes as the complex eigenvectors, and a
  // real LU of it costs a quarter of a complex one; the sum over the poles
  // stays real too (frf_pole_sum.h).
  const Eigen::MatrixXd& pv = es.pseudoEigenvectors();
  f.top = pv.topRows(n);
  Eigen::MatrixXd bs = Eigen::MatrixXd::Zero(2 * n, n);  // state input [0; M^-1]
  bs.bottomRows(n) = Eigen::MatrixXd(sys.m).ldlt().solve(Eigen::MatrixXd::Identity(n, n)) / s;
  f.right = pv.partialPivLu().solve(bs);
  return f;
}

Eigen::MatrixXcd lateral_frf_modal(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w,
                                   FrfReport& report) {
  using cd = std::complex<double>;
  const double t0 = now_s();
  const Eigen::Index n = sys.size(), n_out = maps.c_out.rows(), n_in = maps.b_in.cols();
  report.method = "modal, all eigenvalues (dense)";
  if (n_out == 0 || n_in == 0) return Eigen::MatrixXcd(static_cast<Eigen::Index>(w.size()), n_out * n_in);

  const ModalFactors f = modal_factors(sys);
  const Eigen::VectorXcd& lam = f.eigenvalues;
  const PoleSum sum(lam, maps.c_out * f.top, f.right * maps.b_in);
  const Eigen::Index ns = 2 * n;
  report.poles = static_cast<int>(ns);
  for (Eigen::Index i = 0; i < ns; ++i) report.poles_in_band += std::abs(lam(i)) <= w.back() ? 1 : 0;
  report.setup_s = seconds_since(t0);

  // H(s) = Cout P (s I - D)^-1 P^-1 B_s: alpha = j w, beta = 1.
  const double t1 = now_s();
  const Eigen::Index lines = static_cast<Eigen::Index>(w.size());
  Eigen::VectorXcd jw(lines);
  for (Eigen::Index l = 0; l < lines; ++l) jw(l) = cd(0.0, w[static_cast<size_t>(l)]);
  const Eigen::MatrixXcd h = sum.evaluate(jw, Eigen::VectorXcd::Ones(lines));
  report.lines_s = seconds_since(t1);
  return h;
}

}  // namespace ambdiag::detail
