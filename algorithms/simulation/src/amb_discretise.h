// Exact zero-order-hold discretisation and the spectral radius, private to
// the AMB loop (amb_loop.h); kept in their own translation unit because the
// matrix exponential and the nonsymmetric eigensolver are heavy to compile.
#pragma once

#include <Eigen/Core>

namespace ambdiag::detail {

// x' = A x + B u with u held over [0, h): x(h) = Phi x(0) + Gamma u, in
// balanced coordinates x = D x_b (D diagonal, powers of two, chosen so that
// rows and columns of [[A B][0 0]] have comparable norms: the FE model's
// stiff modes would otherwise make the exponential lose digits).
struct ZohModel {
  Eigen::MatrixXd phi;    // balanced: x_b(h) = phi x_b(0) + gamma u
  Eigen::MatrixXd gamma;
  Eigen::VectorXd scale;  // D: x = D x_b
};
ZohModel zoh_discretise(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double h_s);

// max |eig(m)|.
double spectral_radius(const Eigen::MatrixXd& m);

}  // namespace ambdiag::detail
