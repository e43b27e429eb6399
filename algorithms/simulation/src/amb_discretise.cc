#include "amb_discretise.h"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/MatrixFunctions>

namespace ambdiag::detail {

namespace {

// Parlett-Reinsch balancing of the state rows/columns (the input columns
// keep their scale): returns D with D^-1 M D balanced.
Eigen::VectorXd balance(const Eigen::MatrixXd& m, Eigen::Index n_states) {
  Eigen::VectorXd d = Eigen::VectorXd::Ones(m.rows());
  Eigen::MatrixXd w = m.cwiseAbs();
  for (int sweep = 0; sweep < 100; ++sweep) {
    bool changed = false;
    for (Eigen::Index i = 0; i < n_states; ++i) {
      double c = 0, r = 0;
      for (Eigen::Index k = 0; k < m.rows(); ++k) {
        if (k == i) continue;
        c += w(k, i) * d(i) / d(k);
        r += w(i, k) * d(k) / d(i);
      }
      if (c == 0.0 || r == 0.0) continue;
      // A power of two f with c f ~ r / f (Numerical Recipes, balanc).
      const double s = c + r;
      double f = 1.0, cf2 = c;
      while (cf2 < r / 2.0) f *= 2.0, cf2 *= 4.0;
      while (cf2 > r * 2.0) f /= 2.0, cf2 /= 4.0;
      if ((cf2 + r) / f < 0.95 * s) {
        d(i) *= f;
        changed = true;
      }
    }
    if (!changed) break;
  }
  return d;
}

}  // namespace

ZohModel zoh_discretise(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double h_s) {
  const Eigen::Index n = a.rows(), m = b.cols();
  Eigen::MatrixXd aug = Eigen::MatrixXd::Zero(n + m, n + m);
  aug.topLeftCorner(n, n) = a * h_s;
  aug.topRightCorner(n, m) = b * h_s;
  const Eigen::VectorXd d = balance(aug, n);
  const Eigen::MatrixXd bal = d.cwiseInverse().asDiagonal() * aug * d.asDiagonal();
  const Eigen::MatrixXd e = bal.exp();
  ZohModel z;
  z.phi = e.topLeftCorner(n, n);
  // Input columns were not scaled (d = 1 there): gamma maps u itself.
  z.gamma = e.topRightCorner(n, m);
  z.scale = d.head(n);
  return z;
}

double spectral_radius(const Eigen::MatrixXd& m) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(m, false);
  return es.eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace ambdiag::detail
