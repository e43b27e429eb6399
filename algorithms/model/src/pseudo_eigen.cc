#include "pseudo_eigen.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <vector>

#include "vector_kernels.h"

namespace ambdiag::detail {

namespace {

using cd = std::complex<double>;

constexpr double kEps = std::numeric_limits<double>::epsilon();
// Backward error below which an inverse-iteration vector is accepted (a few
// thousand round-offs of ||H||, as dlaein's growth test).
constexpr double kVectorTol = 1e-12;
// Eigenvalues closer than this (relative to ||T||) count as multiple.
constexpr double kMinGap = 1e-10;

// Complex products written out: std::complex arithmetic checks for NaN and
// calls the library on every division.
inline cd mul(cd a, cd b) { return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()}; }
inline double abs2(cd a) { return a.real() * a.real() + a.imag() * a.imag(); }
inline cd inv(cd a) {
  const double s = 1.0 / (a.real() * a.real() + a.imag() * a.imag());
  return {a.real() * s, -a.imag() * s};
}

double max_abs(const Eigen::VectorXcd& x) {
  double m2 = 0.0;
  for (Eigen::Index i = 0; i < x.size(); ++i) m2 = std::max(m2, abs2(x(i)));
  return std::sqrt(m2);
}

double sign_of(double a, double b) { return b >= 0.0 ? std::abs(a) : -std::abs(a); }

// Eigenvalues of the upper Hessenberg matrix h (overwritten) by Francis
// double-shift QR without Schur vectors: the transformations touch only the
// active window (Golub & Van Loan, Matrix Computations, 4th ed., alg. 7.5.2;
// the deflation, shift and exceptional-shift rules of EISPACK hqr). Roots in
// deflation order from the bottom; a pair u + jv (v > 0) first. False if an
// eigenvalue takes more than 60 iterations.
bool hessenberg_eigenvalues(Eigen::MatrixXd& h, Eigen::VectorXcd& lam) {
  const Eigen::Index n = h.rows();
  lam.resize(n);
  double anorm = 0.0;
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = std::max<Eigen::Index>(i - 1, 0); j < n; ++j) anorm += std::abs(h(i, j));
  Eigen::Index nn = n - 1;
  double shift_sum = 0.0;  // exceptional shifts applied so far
  while (nn >= 0) {
    int its = 0;
    Eigen::Index l = 0;
    do {
      // A negligible subdiagonal entry splits the window [l, nn].
      for (l = nn; l > 0; --l) {
        double s = std::abs(h(l - 1, l - 1)) + std::abs(h(l, l));
        if (s == 0.0) s = anorm;
        if (std::abs(h(l, l - 1)) + s == s) {
          h(l, l - 1) = 0.0;
          break;
        }
      }
      double x = h(nn, nn);
      if (l == nn) {  // one root
        lam(nn--) = x + shift_sum;
        continue;
      }
      double y = h(nn - 1, nn - 1), w = h(nn, nn - 1) * h(nn - 1, nn);
      if (l == nn - 1) {  // two roots of the trailing 2 x 2 block
        const double p = 0.5 * (y - x), q = p * p + w;
        double z = std::sqrt(std::abs(q));
        x += shift_sum;
        if (q >= 0.0) {
          z = p + sign_of(z, p);
          lam(nn - 1) = lam(nn) = x + z;
          if (z != 0.0) lam(nn) = x - w / z;
        } else {
          lam(nn - 1) = cd(x + p, z);
          lam(nn) = cd(x + p, -z);
        }
        nn -= 2;
        continue;
      }
      if (its == 60) return false;
      if (its % 10 == 0 && its > 0) {  // exceptional shift
        shift_sum += x;
        for (Eigen::Index i = 0; i <= nn; ++i) h(i, i) -= x;
        const double s = std::abs(h(nn, nn - 1)) + std::abs(h(nn - 1, nn - 2));
        x = y = 0.75 * s;
        w = -0.4375 * s * s;
      }
      ++its;
      // Start of the bulge: the first column of (H - s1)(H - s2), from the
      // lowest row m where the chase can begin without disturbing l..m.
      Eigen::Index m = nn - 2;
      double p = 0.0, q = 0.0, r = 0.0;
      for (; m >= l; --m) {
        const double z = h(m, m);
        const double rr = x - z, ss = y - z;
        p = (rr * ss - w) / h(m + 1, m) + h(m, m + 1);
        q = h(m + 1, m + 1) - z - rr - ss;
        r = h(m + 2, m + 1);
        const double s = std::abs(p) + std::abs(q) + std::abs(r);
        p /= s;
        q /= s;
        r /= s;
        if (m == l) break;
        const double u = std::abs(h(m, m - 1)) * (std::abs(q) + std::abs(r));
        const double v = std::abs(p) * (std::abs(h(m - 1, m - 1)) + std::abs(z) + std::abs(h(m + 1, m + 1)));
        if (u + v == v) break;
      }
      for (Eigen::Index i = m + 2; i <= nn; ++i) {
        h(i, i - 2) = 0.0;
        if (i != m + 2) h(i, i - 3) = 0.0;
      }
      // Chase the bulge with 3 x 3 reflectors I - [1 y z]^T [x y z] / ...
      for (Eigen::Index k = m; k <= nn - 1; ++k) {
        double scale = 1.0;
        if (k != m) {
          p = h(k, k - 1);
          q = h(k + 1, k - 1);
          r = k != nn - 1 ? h(k + 2, k - 1) : 0.0;
          scale = std::abs(p) + std::abs(q) + std::abs(r);
          if (scale != 0.0) {
            p /= scale;
            q /= scale;
            r /= scale;
          }
        }
        const double s = sign_of(std::sqrt(p * p + q * q + r * r), p);
        if (s == 0.0) continue;
        if (k == m) {
          if (l != m) h(k, k - 1) = -h(k, k - 1);
        } else {
          h(k, k - 1) = -s * scale;
        }
        p += s;
        const double vx = p / s, vy = q / s, vz = r / s;
        q /= p;
        r /= p;
        const bool three = k != nn - 1;
        for (Eigen::Index j = k; j <= nn; ++j) {  // rows k..k+2
          double t = h(k, j) + q * h(k + 1, j);
          if (three) {
            t += r * h(k + 2, j);
            h(k + 2, j) -= t * vz;
          }
          h(k + 1, j) -= t * vy;
          h(k, j) -= t * vx;
        }
        const Eigen::Index last = std::min(nn, k + 3);  // columns k..k+2, rows l..last
        reflect_columns(&h(l, k), &h(l, k + 1), three ? &h(l, k + 2) : nullptr, last - l + 1, vx, vy, vz, q, r);
      }
    } while (l + 1 < nn);
  }
  return true;
}

// T = Q H Q^T by Householder reflectors (Golub & Van Loan, alg. 7.4.2),
// overwriting t with H; the reflectors as in PseudoEigen.
void hessenberg_reduce(Eigen::MatrixXd& t, Eigen::MatrixXd& reflectors, Eigen::VectorXd& taus) {
  const Eigen::Index m = t.rows();
  reflectors = Eigen::MatrixXd::Zero(m, std::max<Eigen::Index>(m - 2, 0));
  taus = Eigen::VectorXd::Zero(std::max<Eigen::Index>(m - 2, 0));
  Eigen::VectorXd work(m);
  for (Eigen::Index k = 0; k + 2 < m; ++k) {
    const Eigen::Index len = m - k - 1;
    double* x = &t(k + 1, k);
    double tail = 0.0;
    for (Eigen::Index i = 1; i < len; ++i) tail += x[i] * x[i];
    if (tail == 0.0) continue;  // already reduced: H_k = I
    const double alpha = x[0], beta = alpha >= 0.0 ? -std::sqrt(alpha * alpha + tail) : std::sqrt(alpha * alpha + tail);
    const double tau = (beta - alpha) / beta, scale = 1.0 / (alpha - beta);
    double* v = &reflectors(k + 1, k);
    v[0] = 1.0;
    for (Eigen::Index i = 1; i < len; ++i) v[i] = x[i] * scale;
    x[0] = beta;
    for (Eigen::Index i = 1; i < len; ++i) x[i] = 0.0;
    taus(k) = tau;
    reflect_left(&t(k + 1, k + 1), m, len, len, v, tau);
    reflect_right(&t(0, k + 1), m, m, len, v, tau, work.data());
  }
}

bool clustered(const Eigen::VectorXcd& lam, double scale) {
  const Eigen::Index m = lam.size();
  for (Eigen::Index i = 0; i < m; ++i)
    for (Eigen::Index j = i + 1; j < m; ++j)
      if (abs2(lam(i) - lam(j)) <= (kMinGap * scale) * (kMinGap * scale)) return true;
  return false;
}

PseudoEigen with_eigen_solver(const Eigen::MatrixXd& t) {
  const Eigen::EigenSolver<Eigen::MatrixXd> es(t);
  if (es.info() != Eigen::Success) throw std::runtime_error("eigenproblem of a projected matrix did not converge");
  PseudoEigen out;
  out.eigenvalues = es.eigenvalues();
  out.x = es.pseudoEigenvectors();
  out.x_lu.compute(out.x);
  out.used_inverse_iteration = false;
  return out;
}

}  // namespace

bool hessenberg_eigenvector(const Eigen::MatrixXd& h, cd lambda, Eigen::VectorXcd& x) {
  const Eigen::Index m = h.rows();
  x.setOnes(m);
  if (m == 0) return true;
  const double hnorm = std::max(h.cwiseAbs().colwise().sum().maxCoeff(), std::numeric_limits<double>::min());
  const double eps3 = hnorm * kEps;  // replaces an exactly zero pivot
  // LU of B = H - lambda I with partial pivoting between neighbouring rows
  // (L unit lower bidiagonal up to the swaps). Rows contiguous, real and
  // imaginary parts apart, so that the row operations are vector kernels.
  using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMatrixXd br(m, m), bi(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    // Entries left of the subdiagonal are never read.
    for (Eigen::Index j = std::max<Eigen::Index>(0, i - 1); j < m; ++j) {
      br(i, j) = h(i, j);
      bi(i, j) = 0.0;
    }
    br(i, i) -= lambda.real();
    bi(i, i) = -lambda.imag();
  }
  std::vector<cd> mult(static_cast<size_t>(m), 0.0);
  std::vector<char> swapped(static_cast<size_t>(m), 0);
  std::vector<double> tmp(static_cast<size_t>(m));
  for (Eigen::Index i = 0; i + 1 < m; ++i) {
    double *rr = &br(i, 0), *ri = &bi(i, 0), *nr = &br(i + 1, 0), *ni = &bi(i + 1, 0);
    if (nr[i] * nr[i] + ni[i] * ni[i] > rr[i] * rr[i] + ri[i] * ri[i]) {
      // memcpy: the library's vector copies (std::swap_ranges is scalar).
      const size_t bytes = static_cast<size_t>(m - i) * sizeof(double);
      std::memcpy(tmp.data(), rr + i, bytes);
      std::memcpy(rr + i, nr + i, bytes);
      std::memcpy(nr + i, tmp.data(), bytes);
      std::memcpy(tmp.data(), ri + i, bytes);
      std::memcpy(ri + i, ni + i, bytes);
      std::memcpy(ni + i, tmp.data(), bytes);
      swapped[static_cast<size_t>(i)] = 1;
    }
    if (rr[i] == 0.0 && ri[i] == 0.0) rr[i] = eps3;
    const cd l = mul(cd(nr[i], ni[i]), inv(cd(rr[i], ri[i])));
    mult[static_cast<size_t>(i)] = l;
    complex_axpy(l.real(), l.imag(), rr + i + 1, ri + i + 1, nr + i + 1, ni + i + 1, m - i - 1);
  }
  if (br(m - 1, m - 1) == 0.0 && bi(m - 1, m - 1) == 0.0) br(m - 1, m - 1) = eps3;
  // U x = v; the first step skips L (the start vector is arbitrary), later
  // ones are true inverse-iteration steps x <- B^-1 x / ||x||.
  Eigen::VectorXcd v = Eigen::VectorXcd::Ones(m);
  Eigen::VectorXd xr(m), xi(m);
  for (int step = 0; step < 3; ++step) {
    if (step > 0) {
      v = x / max_abs(x);
      for (Eigen::Index i = 0; i + 1 < m; ++i) {
        if (swapped[static_cast<size_t>(i)]) std::swap(v(i), v(i + 1));
        v(i + 1) -= mul(mult[static_cast<size_t>(i)], v(i));
      }
    }
    for (Eigen::Index i = m - 1; i >= 0; --i) {
      double sr = 0.0, si = 0.0;
      complex_dot(&br(i, 0) + i + 1, &bi(i, 0) + i + 1, xr.data() + i + 1, xi.data() + i + 1, m - i - 1, &sr, &si);
      const cd xv = mul(v(i) - cd(sr, si), inv(cd(br(i, i), bi(i, i))));
      xr(i) = xv.real();
      xi(i) = xv.imag();
    }
    for (Eigen::Index i = 0; i < m; ++i) x(i) = cd(xr(i), xi(i));
    // B x = P^T L v, and |L v| <= 2 |v| entrywise-max for a bidiagonal L.
    const double xmax = max_abs(x);
    if (!std::isfinite(xmax)) return false;
    const double vmax = max_abs(v);
    if (2.0 * vmax <= kVectorTol * hnorm * xmax) {
      x /= xmax;
      return true;
    }
  }
  return false;
}

PseudoEigen pseudo_eigen(const Eigen::MatrixXd& t) {
  const Eigen::Index m = t.rows();
  if (t.cols() != m) throw std::logic_error("pseudo_eigen: matrix not square");
  if (m < 3) return with_eigen_solver(t);
  PseudoEigen out;
  Eigen::MatrixXd h = t;
  hessenberg_reduce(h, out.reflectors, out.taus);
  Eigen::MatrixXd work = h;
  if (!hessenberg_eigenvalues(work, out.eigenvalues)) throw std::runtime_error("eigenproblem of a projected matrix did not converge");
  const double scale = std::max(t.cwiseAbs().colwise().sum().maxCoeff(), std::numeric_limits<double>::min());
  if (clustered(out.eigenvalues, scale)) return with_eigen_solver(t);
  Eigen::MatrixXd& x = out.x;
  x.resize(m, m);
  Eigen::VectorXcd v;
  for (Eigen::Index i = 0; i < m; ++i) {
    const bool pair = out.eigenvalues(i).imag() != 0.0;
    if (!hessenberg_eigenvector(h, out.eigenvalues(i), v)) return with_eigen_solver(t);
    x.col(i) = v.real();
    if (pair) x.col(++i) = v.imag();
  }
  out.x_lu.compute(x);
  return out;
}

Eigen::MatrixXd PseudoEigen::left_times(const Eigen::MatrixXd& l) const {
  Eigen::MatrixXd lq = l;  // L Q: the reflectors from the right, first to last
  const Eigen::Index m = x.rows();
  Eigen::VectorXd work(l.rows());
  for (Eigen::Index k = 0; k < taus.size(); ++k)
    if (taus(k) != 0.0)
      reflect_right(lq.data() + (k + 1) * lq.rows(), lq.rows(), lq.rows(), m - k - 1, reflectors.col(k).data() + k + 1,
                    taus(k), work.data());
  return lq * x;
}

Eigen::MatrixXd PseudoEigen::solve(const Eigen::MatrixXd& r) const {
  Eigen::MatrixXd qr = r;  // Q^T R: the reflectors from the left, first to last
  const Eigen::Index m = x.rows();
  for (Eigen::Index k = 0; k < taus.size(); ++k)
    if (taus(k) != 0.0)
      reflect_left(qr.data() + k + 1, qr.rows(), m - k - 1, qr.cols(), reflectors.col(k).data() + k + 1, taus(k));
  return x_lu.solve(qr);
}

Eigen::MatrixXd PseudoEigen::vectors() const {
  return left_times(Eigen::MatrixXd::Identity(x.rows(), x.rows()));
}

}  // namespace ambdiag::detail
