#include "rotor_krylov.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <random>
#include <stdexcept>

#include "ambdiag/core/error.h"
#include "frf_lateral.h"
#include "frf_pole_sum.h"
#include "pseudo_eigen.h"
#include "vector_kernels.h"

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;

// Below this reciprocal pivot ratio P(sigma) counts as singular and another
// shift is tried.
constexpr double kMinRcond = 1e-14;
constexpr double kGoldenRatio = 1.618033988749895;
// Up to this many DOFs P(sigma) is factorized dense (an 88-DOF pump with
// structural damping of rank 84: Woodbury would cost more than the LU).
constexpr Eigen::Index kDenseMaxDofs = 200;

Eigen::MatrixXd random_block(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::MatrixXd x(rows, cols);
  for (Eigen::Index j = 0; j < cols; ++j)
    for (Eigen::Index i = 0; i < rows; ++i) x(i, j) = uni(rng);
  return x;
}

// The operator at the first of a few shifts sigma0 * 1.618^k where P(sigma)
// is regular (a shift on an overdamped eigenvalue is singular).
std::unique_ptr<ShiftInvert> make_operator(const RotorSystem& sys, double sigma0, double scale) {
  double sigma = sigma0;
  for (int attempt = 0; attempt < 4; ++attempt, sigma *= kGoldenRatio) {
    auto op = std::make_unique<ShiftInvert>(sys, sigma, scale);
    if (op->ok()) return op;
  }
  throw InputError("rotor system: the dynamic stiffness K + s C + s^2 M is singular at every trial shift");
}

struct Ritz {
  Eigen::VectorXcd theta;
  Eigen::MatrixXcd w;         // unit eigenvectors of T
  Eigen::VectorXd residual;  // ||Op x - theta x|| / |theta|, x = V w
};

Ritz ritz_pairs(const BlockArnoldi& a) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(a.projected());
  if (es.info() != Eigen::Success) throw std::runtime_error("Krylov: eigenproblem of the projected matrix failed");
  Ritz r;
  r.theta = es.eigenvalues();
  r.w = es.eigenvectors();
  const Eigen::MatrixXcd fw = a.coupling().cast<cd>() * r.w.bottomRows(a.block());
  r.residual.resize(r.theta.size());
  for (Eigen::Index i = 0; i < r.theta.size(); ++i) {
    r.residual(i) = fw.col(i).norm() / std::max(std::abs(r.theta(i)), 1e-300);
  }
  return r;
}

}  // namespace

ShiftInvert::ShiftInvert(const RotorSystem& sys, double sigma, double scale)
    : sys_(sys), n_(sys.size()), sigma_(sigma), scale_(scale) {
  if (sigma == 0.0 || !(scale > 0.0)) throw std::logic_error("ShiftInvert: sigma must be nonzero and scale > 0");
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < sys.damping_d.size(); ++i)
    if (sys.damping_d(i) > 0.0) keep.push_back(i);
  const Eigen::Index r = static_cast<Eigen::Index>(keep.size());
  u_.resize(n_, r);
  d_.resize(r);
  for (Eigen::Index i = 0; i < r; ++i) {
    u_.col(i) = sys.damping_u.col(keep[static_cast<size_t>(i)]);
    d_(i) = sys.damping_d(keep[static_cast<size_t>(i)]);
  }
  if (n_ <= kDenseMaxDofs) {
    // Small system: C_t dense, P(sigma) by a dense LU (cheaper than KLU
    // plus a Woodbury update of rank up to n).
    dense_ = true;
    Eigen::MatrixXd ct = Eigen::MatrixXd(sys.c);
    if (r > 0) ct.noalias() += u_ * d_.asDiagonal() * u_.transpose();
    const Eigen::MatrixXd m = Eigen::MatrixXd(sys.m);
    dense_lu_.compute(Eigen::MatrixXd(sys.k) + sigma * ct + (sigma * sigma) * m);
    ct_sigma_m_ = ct + sigma * m;
    // Reciprocal pivot ratio, as KLU's rcond.
    const Eigen::VectorXd piv = dense_lu_.matrixLU().diagonal().cwiseAbs();
    ok_ = n_ > 0 && piv.minCoeff() >= kMinRcond * piv.maxCoeff();
    return;
  }
  KluReal::Matrix p0 = sys.k + sigma * sys.c + (sigma * sigma) * sys.m;
  p0.makeCompressed();
  lu_ = std::make_unique<KluReal>(p0);
  if (lu_->rcond() < kMinRcond) return;
  if (r > 0) {
    // Woodbury: P = P0 + U (sigma D) U^T.
    p0u_ = u_;
    lu_->solve_in_place(p0u_);
    Eigen::MatrixXd cap = u_.transpose() * p0u_;
    cap.diagonal() += (sigma * d_).cwiseInverse();
    capacitance_.compute(cap);
    if (!(capacitance_.rcond() >= kMinRcond)) return;
  }
  ok_ = true;
}

Eigen::MatrixXd ShiftInvert::solve(Eigen::MatrixXd rhs) const {
  if (dense_) {
    Eigen::MatrixXd x = dense_lu_.permutationP() * rhs;
    lu_solve_in_place(dense_lu_.matrixLU().data(), n_, x.data(), x.cols());
    return x;
  }
  lu_->solve_in_place(rhs);
  if (u_.cols() > 0) rhs.noalias() -= p0u_ * capacitance_.solve(Eigen::MatrixXd(u_.transpose() * rhs));
  return rhs;
}

Eigen::MatrixXd ShiftInvert::damping_times(const Eigen::MatrixXd& x) const {
  Eigen::MatrixXd y = sys_.c * x;
  if (u_.cols() > 0) y.noalias() += u_ * (d_.asDiagonal() * (u_.transpose() * x));
  return y;
}

Eigen::MatrixXd ShiftInvert::apply(const Eigen::MatrixXd& x) const {
  const Eigen::MatrixXd b1 = x.topRows(n_), b2 = x.bottomRows(n_);
  Eigen::MatrixXd rhs = -scale_ * (sys_.m * b2);
  if (dense_) {
    subtract_product(ct_sigma_m_.data(), n_, n_, b1.data(), b1.cols(), rhs.data());
  } else {
    rhs -= damping_times(b1) + sigma_ * (sys_.m * b1);
  }
  const Eigen::MatrixXd x1 = solve(rhs);
  Eigen::MatrixXd y(2 * n_, x.cols());
  y.topRows(n_) = x1;
  y.bottomRows(n_) = (b1 + sigma_ * x1) / scale_;
  return y;
}

Eigen::MatrixXd ShiftInvert::apply_to_forces(const Eigen::MatrixXd& f) const {
  const Eigen::MatrixXd x1 = solve(-f);
  Eigen::MatrixXd y(2 * n_, f.cols());
  y.topRows(n_) = x1;
  y.bottomRows(n_) = (sigma_ / scale_) * x1;
  return y;
}

BlockArnoldi::BlockArnoldi(const ShiftInvert& op, const Eigen::MatrixXd& start, unsigned seed)
    : op_(op), p_(static_cast<int>(start.cols())), seed_(seed) {
  const Eigen::Index n = op.state_size();
  if (p_ < 1 || p_ > n || start.rows() != n) throw std::logic_error("BlockArnoldi: bad start block");
  v_.resize(n, std::min<Eigen::Index>(n, 8 * p_));
  Eigen::MatrixXd w = start;
  beta_ = orthonormalize(w, 0);
  v_.leftCols(p_) = w;
}

Eigen::MatrixXd BlockArnoldi::orthonormalize(Eigen::MatrixXd& w, int k) {
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(p_, p_);
  const Eigen::Index n = w.rows();
  for (int j = 0; j < p_; ++j) {
    auto col = w.col(j);
    const double ref = col.norm();
    for (int pass = 0; pass < 2; ++pass) {
      for (int i = 0; i < j; ++i) {
        const double c = w.col(i).dot(col);
        col -= c * w.col(i);
        r(i, j) += c;
      }
    }
    const double nrm = col.norm();
    if (nrm > 1e-12 * ref && nrm > 0.0) {
      r(j, j) = nrm;
      col /= nrm;
      continue;
    }
    // Rank lost: continue with a random direction; its coefficient is zero
    // (the dropped remainder is below round-off of the block).
    Eigen::VectorXd x = random_block(n, 1, seed_ + static_cast<unsigned>(k + j)).col(0);
    for (int pass = 0; pass < 2; ++pass) {
      x -= v_.leftCols(k) * (v_.leftCols(k).transpose() * x);
      for (int i = 0; i < j; ++i) x -= w.col(i).dot(x) * w.col(i);
    }
    col = x / x.norm();
  }
  return r;
}

bool BlockArnoldi::extend() {
  const Eigen::Index n = op_.state_size();
  const int k = m_ + p_;  // columns in use
  if (k + p_ > n) return false;
  if (v_.cols() < k + p_) v_.conservativeResize(Eigen::NoChange, std::min<Eigen::Index>(n, std::max<Eigen::Index>(k + p_, 2 * v_.cols())));
  Eigen::MatrixXd w = op_.apply(v_.middleCols(m_, p_));
  // Classical Gram-Schmidt, twice, against the k columns in use.
  Eigen::MatrixXd coef(k, p_), again(k, p_);
  gram(v_.data(), n, k, w.data(), p_, coef.data());
  subtract_product(v_.data(), n, k, coef.data(), p_, w.data());
  gram(v_.data(), n, k, w.data(), p_, again.data());
  subtract_product(v_.data(), n, k, again.data(), p_, w.data());
  coef += again;
  const Eigen::MatrixXd r = orthonormalize(w, k);
  h_.conservativeResizeLike(Eigen::MatrixXd::Zero(k + p_, k));
  h_.block(0, m_, k, p_) = coef;
  h_.block(k, m_, p_, p_) = r;
  v_.middleCols(k, p_) = w;
  m_ = k;
  return true;
}

BandModes rotor_modes_in_band(const RotorSystem& sys, double band, bool shapes) {
  if (!(band > 0.0) || !std::isfinite(band)) throw std::logic_error("rotor_modes_in_band: band must be finite and > 0");
  const auto op = make_operator(sys, -0.5 * band, band);
  const Eigen::Index n = sys.size(), big_n = op->state_size();
  const int p = static_cast<int>(std::min<Eigen::Index>(4, big_n));
  BlockArnoldi arnoldi(*op, random_block(big_n, p, 1234u), 4321u);
  // Every eigenvalue with |lambda| <= band has |lambda - sigma| <= band +
  // |sigma|, so |theta| >= theta_band; a margin covers Ritz values still
  // moving towards it.
  const double sigma = op->sigma();
  const double theta_band = 1.0 / (band + std::abs(sigma));
  constexpr double kTol = 1e-10;
  constexpr int kMaxSize = 1000;
  auto tol_of = [&](cd lam) { return std::abs(lam) <= 1e-6 * band ? 1e-5 : kTol; };  // zero roots are defective
  int next_check = std::max(24, 4 * p), last_count = -1;
  for (;;) {
    bool room = true;
    while (arnoldi.size() < next_check && (room = arnoldi.extend())) {
    }
    const bool last = !room || arnoldi.size() >= kMaxSize;
    const Ritz r = ritz_pairs(arnoldi);
    bool settled = true;
    int count = 0;
    for (Eigen::Index i = 0; i < r.theta.size(); ++i) {
      const cd lam = sigma + 1.0 / r.theta(i);
      const bool conv = r.residual(i) <= tol_of(lam);
      if (std::abs(r.theta(i)) >= 0.8 * theta_band && !conv) settled = false;
      if (std::abs(lam) <= band && conv) ++count;
    }
    if (last || (settled && count == last_count)) {
      BandModes out;
      out.krylov_size = arnoldi.size();
      out.converged = settled;
      std::vector<Eigen::Index> keep;
      for (Eigen::Index i = 0; i < r.theta.size(); ++i) {
        const cd lam = sigma + 1.0 / r.theta(i);
        if (std::abs(lam) > band) continue;
        keep.push_back(i);
        out.max_residual = std::max(out.max_residual, r.residual(i));
      }
      const Eigen::Index k = static_cast<Eigen::Index>(keep.size());
      out.eigenvalues.resize(k);
      if (shapes) out.shapes.resize(n, k);
      const Eigen::MatrixXd vq = arnoldi.vectors().topLeftCorner(n, arnoldi.size());
      for (Eigen::Index j = 0; j < k; ++j) {
        const Eigen::Index i = keep[static_cast<size_t>(j)];
        out.eigenvalues(j) = sigma + 1.0 / r.theta(i);
        if (shapes) out.shapes.col(j) = vq * r.w.col(i);
      }
      return out;
    }
    last_count = settled ? count : -1;
    next_check = arnoldi.size() + std::max(2 * p, arnoldi.size() / 4);
  }
}

Eigen::MatrixXcd lateral_frf_modal_krylov(const RotorSystem& sys, const LateralMaps& maps,
                                          const std::vector<double>& w, double tol, FrfReport& report) {
  const double t0 = now_s();
  const Eigen::Index n = sys.size(), n_out = maps.c_out.rows(), n_in = maps.b_in.cols();
  const Eigen::Index lines = static_cast<Eigen::Index>(w.size());
  report.method = "modal, Krylov basis";
  if (n_out == 0 || n_in == 0 || lines == 0) return Eigen::MatrixXcd::Zero(lines, n_out * n_in);
  const double w_max = *std::max_element(w.begin(), w.end());
  const auto op = make_operator(sys, -0.5 * w_max, w_max);
  const double sigma = op->sigma();
  BlockArnoldi arnoldi(*op, op->apply_to_forces(maps.b_in), 777u);
  const int p = arnoldi.block();
  const Eigen::MatrixXd& beta = arnoldi.start_coefficients();  // p x n_in
  const double beta_norm = std::max(beta.norm(), 1e-300);
  // The reduced FRF is L (I - mu T)^-1 E_1 beta with mu = s - sigma: the
  // pole sum of frf_pole_sum.h with alpha = 1, beta = mu.
  Eigen::VectorXcd mu(lines);
  for (Eigen::Index l = 0; l < lines; ++l) mu(l) = cd(-sigma, w[static_cast<size_t>(l)]);
  const Eigen::VectorXcd ones = Eigen::VectorXcd::Ones(lines);

  // Intermediate checks look at a subset of lines (evenly spaced); only
  // when it passes are all lines checked.
  constexpr Eigen::Index kCheckLines = 64;
  const Eigen::Index n_sub = std::min(lines, kCheckLines);
  Eigen::VectorXcd mu_sub(n_sub);
  for (Eigen::Index c = 0; c < n_sub; ++c) mu_sub(c) = mu(lines <= kCheckLines ? c : c * (lines - 1) / (kCheckLines - 1));
  const Eigen::VectorXcd ones_sub = Eigen::VectorXcd::Ones(n_sub);

  // Largest relative residual |mu| ||F E_last^T y|| / ||beta|| over the
  // lines of `sum` (its columns after the H entries hold F E_last^T y).
  const Eigen::Index n_h = n_out * n_in;
  auto worst_residual = [&](const Eigen::MatrixXcd& values, const Eigen::VectorXcd& mus) {
    double worst = 0.0;
    for (Eigen::Index l = 0; l < mus.size(); ++l)
      worst = std::max(worst, std::abs(mus(l)) * values.row(l).tail(p * n_in).norm() / beta_norm);
    return worst;
  };

  constexpr int kMaxSize = 1000;
  int next_check = std::max(24, 4 * p), prev_m = 0;
  double prev_worst = -1.0;
  for (;;) {
    bool room = true;
    while (arnoldi.size() < next_check && (room = arnoldi.extend())) {
    }
    const bool last = !room || arnoldi.size() >= kMaxSize;
    const int m = arnoldi.size();
    // T = P D P^-1 in real arithmetic (D block diagonal); the reduced
    // solve y(s) = P (I - mu D)^-1 P^-1 E_1 beta, H = -Cout V y and the
    // residual rows F E_last^T y share the kernel.
    const PseudoEigen es = pseudo_eigen(arnoldi.projected());
    Eigen::MatrixXd e1b = Eigen::MatrixXd::Zero(m, n_in);
    e1b.topRows(p) = beta;
    Eigen::MatrixXd left = Eigen::MatrixXd::Zero(n_out + p, m);
    left.topRows(n_out).noalias() = -(maps.c_out * arnoldi.vectors().topLeftCorner(n, m));
    left.bottomRightCorner(p, p) = arnoldi.coupling();
    const PoleSum sum(es.eigenvalues, es.left_times(left), es.solve(e1b));
    double worst = worst_residual(sum.evaluate(ones_sub, mu_sub), mu_sub);
    if (worst <= tol || last) {
      const double t1 = now_s();
      const Eigen::MatrixXcd all = sum.evaluate(ones, mu);
      const double lines_s = seconds_since(t1);
      worst = worst_residual(all, mu);
      if (worst <= tol || last) {
        report.krylov_size = m;
        report.krylov_residual = worst;
        report.converged = worst <= tol;
        report.poles = m;
        for (Eigen::Index i = 0; i < m; ++i)
          report.poles_in_band += std::abs(sigma + 1.0 / es.eigenvalues(i)) <= w_max ? 1 : 0;
        report.lines_s = lines_s;
        report.setup_s = seconds_since(t0) - lines_s;
        return all.leftCols(n_h);
      }
    }
    // Next size: once the residual falls geometrically, where its rate
    // predicts the tolerance (within [p, m / 2] more vectors).
    int step = std::max(p, m / 5);
    if (prev_worst > 0 && worst < prev_worst && worst < 1.0) {
      const double rate = std::log(prev_worst / worst) / (m - prev_m);  // per vector
      const double predicted = std::log(worst / tol) / rate;
      step = std::clamp(static_cast<int>(std::ceil(predicted / p)) * p, p, std::max(2 * p, m / 2));
    }
    prev_worst = worst;
    prev_m = m;
    next_check = m + step;
  }
}

}  // namespace ambdiag::detail
