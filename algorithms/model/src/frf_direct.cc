// Direct FRF: sparse complex LU of the dynamic stiffness per line (KLU).
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <complex>
#include <string>

#include "ambdiag/core/error.h"
#include "frf_lateral.h"
#include "klu_complex.h"

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;
using SparseC = KluComplex::Matrix;

// Values of `a` laid out on the (larger) compressed pattern `p`.
Eigen::VectorXcd values_on_pattern(const Eigen::SparseMatrix<double>& a, const SparseC& p) {
  const SparseC on = a.cast<cd>() + cd(0.0) * p;
  if (on.nonZeros() != p.nonZeros()) throw std::logic_error("FRF pattern mismatch");
  return Eigen::Map<const Eigen::VectorXcd>(on.valuePtr(), on.nonZeros());
}

[[noreturn]] void throw_singular(double w) {
  throw InputError("dynamic stiffness is singular at " + std::to_string(w / (2 * M_PI)) +
                   " Hz (an undamped resonance on a line, or a rotor without support and mass)");
}

// Dense complex LU per line: for small systems whose structural damping has
// nearly full rank, where Woodbury would cost more (r solves and an r x r LU).
Eigen::MatrixXcd dense_direct(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w,
                              FrfReport& report) {
  const double t0 = now_s();
  const Eigen::Index n_out = maps.c_out.rows(), n_in = maps.b_in.cols();
  const Eigen::MatrixXcd k = Eigen::MatrixXd(sys.k).cast<cd>(), m = Eigen::MatrixXd(sys.m).cast<cd>(),
                         c = sys.dense_damping().cast<cd>(), b = maps.b_in.cast<cd>(),
                         c_out = maps.c_out.cast<cd>();
  Eigen::MatrixXcd h(static_cast<Eigen::Index>(w.size()), n_out * n_in);
  report.setup_s = seconds_since(t0);
  const double t1 = now_s();
  Eigen::MatrixXcd z(k.rows(), k.cols());
  Eigen::PartialPivLU<Eigen::MatrixXcd> lu(k.rows());
  for (size_t line = 0; line < w.size(); ++line) {
    const double wl = w[line];
    z = k + cd(0.0, wl) * c - (wl * wl) * m;
    lu.compute(z);
    if (!(lu.rcond() > 0.0)) throw_singular(wl);
    const Eigen::MatrixXcd hl = c_out * lu.solve(b);
    for (Eigen::Index o = 0; o < n_out; ++o)
      for (Eigen::Index i = 0; i < n_in; ++i) h(static_cast<Eigen::Index>(line), o * n_in + i) = hl(o, i);
  }
  report.lines_s = seconds_since(t1);
  return h;
}

}  // namespace

Eigen::MatrixXcd lateral_frf_direct(const RotorSystem& sys, const LateralMaps& maps, const std::vector<double>& w,
                                    FrfReport& report) {
  const double t0 = now_s();
  const Eigen::Index n_out = maps.c_out.rows(), n_in = maps.b_in.cols();
  Eigen::MatrixXcd h(static_cast<Eigen::Index>(w.size()), n_out * n_in);
  if (n_out == 0 || n_in == 0) return h;

  // One pattern for K, C and M so the symbolic analysis is done once.
  SparseC z = sys.k.cast<cd>() + sys.c.cast<cd>() + sys.m.cast<cd>();
  z.makeCompressed();
  const Eigen::VectorXcd kv = values_on_pattern(sys.k, z), cv = values_on_pattern(sys.c, z),
                         mv = values_on_pattern(sys.m, z);

  // Structural damping C_s = U diag(d) U^T: only columns with d > 0.
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < sys.damping_d.size(); ++i)
    if (sys.damping_d(i) > 0.0) keep.push_back(i);
  const Eigen::Index r = static_cast<Eigen::Index>(keep.size());
  // Per-line cost estimates in complex multiply-adds: a dense LU against
  // KLU (some 20 n entries in L + U for a shaft, used twice per right-hand
  // side) with Woodbury (r more solves, U^T X and an r x r LU).
  constexpr Eigen::Index kDenseMaxDofs = 600;
  const double nd = static_cast<double>(sys.size()), rd = static_cast<double>(r);
  const double dense_cost = nd * nd * nd / 3.0;
  const double sparse_cost = (static_cast<double>(n_in) + rd) * 40.0 * nd + nd * rd * rd + rd * rd * rd / 3.0;
  if (sys.size() <= kDenseMaxDofs && dense_cost < sparse_cost) {
    report.method = "direct, dense LU per line (structural damping of rank " + std::to_string(r) + ")";
    return dense_direct(sys, maps, w, report);
  }
  report.method = "direct, KLU per line" + (r > 0 ? " + Woodbury (rank " + std::to_string(r) + ")" : std::string());
  Eigen::MatrixXd u(sys.size(), r);
  Eigen::VectorXd d(r);
  for (Eigen::Index i = 0; i < r; ++i) {
    u.col(i) = sys.damping_u.col(keep[static_cast<size_t>(i)]);
    d(i) = sys.damping_d(keep[static_cast<size_t>(i)]);
  }
  Eigen::MatrixXcd rhs(sys.size(), n_in + r);
  rhs.leftCols(n_in) = maps.b_in.cast<cd>();
  rhs.rightCols(r) = u.cast<cd>();
  const Eigen::MatrixXcd ut = u.transpose().cast<cd>();
  const Eigen::MatrixXcd c_out = maps.c_out.cast<cd>();

  KluComplex lu(z);
  report.setup_s = seconds_since(t0);
  const double t1 = now_s();
  Eigen::MatrixXcd x;
  Eigen::Map<Eigen::VectorXcd> zv(z.valuePtr(), z.nonZeros());
  for (size_t line = 0; line < w.size(); ++line) {
    const double wl = w[line];
    zv = kv + cd(0.0, wl) * cv - wl * wl * mv;
    if (!lu.factorize(z)) throw_singular(wl);
    x = rhs;
    lu.solve_in_place(x);
    Eigen::MatrixXcd hl = c_out * x.leftCols(n_in);
    if (r > 0) {
      // Woodbury: (Z0 + U (jw D) U^T)^-1 = Z0^-1 - Z0^-1 U S^-1 U^T Z0^-1,
      // S = (jw D)^-1 + U^T Z0^-1 U.
      Eigen::MatrixXcd s = ut * x.rightCols(r);
      s.diagonal() += (cd(0.0, wl) * d.cast<cd>()).cwiseInverse();
      hl -= (c_out * x.rightCols(r)) * s.partialPivLu().solve(ut * x.leftCols(n_in));
    }
    for (Eigen::Index o = 0; o < n_out; ++o)
      for (Eigen::Index i = 0; i < n_in; ++i) h(static_cast<Eigen::Index>(line), o * n_in + i) = hl(o, i);
  }
  report.lines_s = seconds_since(t1);
  return h;
}

}  // namespace ambdiag::detail
