// Free-free plane modes of the bare rotor: dense for small planes, Lanczos
// with sparse LDL^T for large ones (rotor_system.h).
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "ambdiag/algorithms/model/rotor_system.h"
#include "ambdiag/core/error.h"
#include "beam_element.h"

namespace ambdiag {

namespace {

using Sparse = Eigen::SparseMatrix<double>;

// Plane matrices (2 DOF per node: w, theta) of the bare rotor: shaft and disks.
void plane_matrices(const PlantModel& p, Sparse& k, Sparse& m) {
  const int n = 2 * p.node_count();
  std::vector<Eigen::Triplet<double>> tk, tm;
  for (size_t i = 0; i < p.shaft.size(); ++i) {
    const auto& e = p.shaft[i];
    const auto& mat = p.materials.at(e.material);
    const detail::Matrix4 ke = detail::beam_stiffness(e, mat);
    const detail::Matrix4 me = detail::beam_translational_mass(e, mat) + detail::beam_rotary_mass(e, mat);
    const int base = 2 * static_cast<int>(i);
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) {
        tk.emplace_back(base + r, base + c, ke(r, c));
        tm.emplace_back(base + r, base + c, me(r, c));
      }
  }
  for (const auto& d : p.disks) {
    tm.emplace_back(2 * d.node, 2 * d.node, d.m_kg);
    tm.emplace_back(2 * d.node + 1, 2 * d.node + 1, d.id_kg_m2);
  }
  k.resize(n, n);
  m.resize(n, n);
  k.setFromTriplets(tk.begin(), tk.end());
  m.setFromTriplets(tm.begin(), tm.end());
}

// Number of elastic modes to return among ascending `omega`.
int wanted_count(const Eigen::VectorXd& omega_elastic, const PlaneModeOptions& o) {
  int n = 0;
  while (n < omega_elastic.size() && omega_elastic(n) <= o.omega_max_rad_per_s) ++n;
  return o.max_elastic >= 0 ? std::min(n, o.max_elastic) : n;
}

PlaneModes dense_plane_modes(const Sparse& k, const Sparse& m, const PlaneModeOptions& o) {
  // M is positive definite for any shaft with positive density; K is
  // singular (two rigid-body modes).
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es{Eigen::MatrixXd(k), Eigen::MatrixXd(m)};
  if (es.info() != Eigen::Success) throw InputError("free-free rotor: eigenproblem failed (singular mass matrix?)");
  const int n = static_cast<int>(k.rows());
  Eigen::VectorXd omega(n);
  for (int i = 0; i < n; ++i) {
    const double lam = es.eigenvalues()(i);
    omega(i) = (i < 2 || lam <= 0.0) ? 0.0 : std::sqrt(lam);
  }
  const int keep = 2 + wanted_count(omega.tail(n - 2), o);
  PlaneModes out;
  out.solver = "dense";
  out.omega_rad_per_s = omega.head(keep);
  out.shapes = es.eigenvectors().leftCols(keep);
  return out;
}

// Number of eigenvalues of (K, M) below tau: the negative pivots of
// K - tau M (Sylvester's law of inertia); -1 if the factorization failed.
int sturm_count(const Sparse& k, const Sparse& m, double tau) {
  const Sparse a = k - tau * m;
  Eigen::SimplicialLDLT<Sparse> ldlt(a);
  if (ldlt.info() != Eigen::Success) return -1;
  return static_cast<int>((ldlt.vectorD().array() < 0.0).count());
}

// Lanczos on K^+ M in the M inner product, on the M-orthogonal complement of
// the rigid-body modes R. K x = M v is consistent there; it is solved with
// the two end translations held (which removes both rigid-body motions, so
// the held system is positive definite and its solution solves the free
// one exactly), then projected back onto the complement.
class PlaneLanczos {
 public:
  PlaneLanczos(const Sparse& k, const Sparse& m, const std::vector<double>& z) : k_(k), m_(m), n_(static_cast<int>(k.rows())) {
    const int nodes = n_ / 2;
    double zmean = 0.0;
    for (double v : z) zmean += v / nodes;
    rigid_.setZero(n_, 2);
    for (int i = 0; i < nodes; ++i) {
      rigid_(2 * i, 0) = 1.0;                                    // translation
      rigid_(2 * i, 1) = z[static_cast<size_t>(i)] - zmean;  // tilt: w = z, theta = 1
      rigid_(2 * i + 1, 1) = 1.0;
    }
    // M-orthonormal: R L^-T with R^T M R = L L^T.
    const Eigen::LLT<Eigen::Matrix2d> g(rigid_.transpose() * (m_ * rigid_));
    const Eigen::MatrixXd rt = g.matrixL().solve(rigid_.transpose());
    rigid_ = rt.transpose();
    // Held DOFs: w at the first and the last node.
    free_.reserve(static_cast<size_t>(n_ - 2));
    std::vector<int> pos(static_cast<size_t>(n_), -1);
    for (int i = 0; i < n_; ++i) {
      if (i == 0 || i == n_ - 2) continue;
      pos[static_cast<size_t>(i)] = static_cast<int>(free_.size());
      free_.push_back(i);
    }
    std::vector<Eigen::Triplet<double>> t;
    for (int c = 0; c < k_.outerSize(); ++c)
      for (Sparse::InnerIterator it(k_, c); it; ++it) {
        const int r = pos[static_cast<size_t>(it.row())], cc = pos[static_cast<size_t>(it.col())];
        if (r >= 0 && cc >= 0) t.emplace_back(r, cc, it.value());
      }
    Sparse kf(n_ - 2, n_ - 2);
    kf.setFromTriplets(t.begin(), t.end());
    ldlt_.compute(kf);
    if (ldlt_.info() != Eigen::Success || ldlt_.vectorD().minCoeff() <= 0.0) {
      throw InputError("free-free rotor: the stiffness matrix is not positive semi-definite");
    }
  }

  const Eigen::MatrixXd& rigid() const { return rigid_; }
  int dim() const { return n_ - 2; }  // of the complement

  void project(Eigen::Ref<Eigen::VectorXd> v) const { v -= rigid_ * (rigid_.transpose() * (m_ * v)); }

  Eigen::VectorXd apply(const Eigen::VectorXd& v) const {
    const Eigen::VectorXd b = m_ * v;
    Eigen::VectorXd bf(n_ - 2);
    for (size_t i = 0; i < free_.size(); ++i) bf(static_cast<Eigen::Index>(i)) = b(free_[i]);
    const Eigen::VectorXd xf = ldlt_.solve(bf);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n_);
    for (size_t i = 0; i < free_.size(); ++i) x(free_[i]) = xf(static_cast<Eigen::Index>(i));
    project(x);
    return x;
  }

  PlaneModes run(const PlaneModeOptions& o) {
    constexpr double kTol = 1e-10;  // relative Ritz residual
    const int cap = dim();
    Eigen::MatrixXd v(n_, std::min(cap, 64));
    std::vector<double> alpha, beta;
    std::mt19937 rng(20240517);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    auto fresh = [&](int cols) {  // random vector M-orthogonal to R and V(:, 0:cols)
      Eigen::VectorXd x(n_);
      for (int i = 0; i < n_; ++i) x(i) = uni(rng);
      for (int pass = 0; pass < 2; ++pass) {
        project(x);
        x -= v.leftCols(cols) * (v.leftCols(cols).transpose() * (m_ * x));
      }
      return Eigen::VectorXd(x / std::sqrt(x.dot(m_ * x)));
    };
    v.col(0) = fresh(0);
    PlaneModes out;
    out.solver = "lanczos";
    int next_check = std::min(cap, std::max(12, o.max_elastic >= 0 ? o.max_elastic + 6 : 12));
    for (int j = 0; j < cap; ++j) {
      if (j + 1 >= v.cols() && v.cols() < cap) v.conservativeResize(Eigen::NoChange, std::min(cap, 2 * static_cast<int>(v.cols())));
      Eigen::VectorXd w = apply(v.col(j));
      const double a = v.col(j).dot(m_ * w);
      alpha.push_back(a);
      // Full reorthogonalisation (twice is enough, Parlett): the Krylov
      // vectors stay M-orthonormal to round-off, so no spurious copies.
      for (int pass = 0; pass < 2; ++pass) {
        w -= v.leftCols(j + 1) * (v.leftCols(j + 1).transpose() * (m_ * w));
        project(w);
      }
      double b = std::sqrt(std::max(0.0, w.dot(m_ * w)));
      const bool last = j + 1 == cap;
      if (!last) {
        if (b <= 1e-13 * std::abs(a)) {
          // Invariant subspace: continue with a fresh direction (the
          // tridiagonal matrix splits there).
          b = 0.0;
          v.col(j + 1) = fresh(j + 1);
        } else {
          v.col(j + 1) = w / b;
        }
      }
      beta.push_back(b);
      if (!last && j + 1 < next_check) continue;
      next_check = std::min(cap, j + 1 + std::max(6, (j + 1) / 4));

      // Ritz pairs of the tridiagonal matrix, largest theta (lowest
      // frequency) first.
      const int m = j + 1;
      Eigen::VectorXd d = Eigen::Map<Eigen::VectorXd>(alpha.data(), m);
      Eigen::VectorXd e = Eigen::Map<Eigen::VectorXd>(beta.data(), m).head(std::max(0, m - 1));
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tri;
      tri.computeFromTridiagonal(d, e, Eigen::ComputeEigenvectors);
      std::vector<int> order(static_cast<size_t>(m));
      for (int i = 0; i < m; ++i) order[static_cast<size_t>(i)] = m - 1 - i;
      int converged = 0;  // leading run of converged Ritz pairs
      Eigen::VectorXd lam(m);
      for (int i = 0; i < m; ++i) {
        const int c = order[static_cast<size_t>(i)];
        const double theta = tri.eigenvalues()(c);
        lam(i) = theta > 0 ? 1.0 / theta : std::numeric_limits<double>::infinity();
        const double resid = std::abs(b * tri.eigenvectors()(m - 1, c));
        if (converged == i && theta > 0 && (last || resid <= kTol * theta)) ++converged;
      }
      int in_band = 0;
      while (in_band < converged && std::sqrt(lam(in_band)) <= o.omega_max_rad_per_s) ++in_band;
      const int want = o.max_elastic >= 0 ? std::min(in_band, o.max_elastic) : in_band;
      // Done when a converged Ritz value beyond the wanted ones shows where
      // the wanted ones end (or the space is exhausted).
      if (!last && converged <= want) continue;
      // Sturm check between the last wanted and the next eigenvalue.
      const double lo = want > 0 ? lam(want - 1) : 0.0;
      const double hi = last && want == m ? 2.0 * lam(m - 1) + 1.0 : lam(want);
      const double tau = lo > 0 ? std::sqrt(lo * hi) : 0.5 * hi;
      const int count = sturm_count(k_, m_, tau);
      out.sturm_checked = count == 2 + want;
      if (!out.sturm_checked && count >= 0 && !last) continue;  // a mode was missed: keep going
      out.iterations = m;
      out.omega_rad_per_s.resize(2 + want);
      out.shapes.resize(n_, 2 + want);
      out.omega_rad_per_s.head(2).setZero();
      out.shapes.leftCols(2) = rigid_;
      for (int i = 0; i < want; ++i) {
        Eigen::VectorXd phi = v.leftCols(m) * tri.eigenvectors().col(order[static_cast<size_t>(i)]);
        const Eigen::VectorXd mphi = m_ * phi;
        phi /= std::sqrt(phi.dot(mphi));
        // Rayleigh quotient: second-order accurate in the vector.
        out.omega_rad_per_s(2 + i) = std::sqrt(std::max(0.0, phi.dot(k_ * phi)));
        out.shapes.col(2 + i) = phi;
      }
      return out;
    }
    throw InputError("free-free rotor: Lanczos did not converge");  // unreachable: the last step always returns
  }

 private:
  const Sparse& k_;
  const Sparse& m_;
  int n_;
  Eigen::MatrixXd rigid_;  // n x 2, M-orthonormal
  std::vector<int> free_;
  Eigen::SimplicialLDLT<Sparse> ldlt_;
};

}  // namespace

PlaneModes free_free_plane_modes(const PlantModel& plant, const PlaneModeOptions& options) {
  Sparse k, m;
  plane_matrices(plant, k, m);
  const int n = static_cast<int>(k.rows());
  constexpr int kDenseMaxDofs = 400;
  const bool every = options.max_elastic < 0 && !std::isfinite(options.omega_max_rad_per_s);
  const bool dense = options.solver == PlaneModeOptions::Solver::dense ||
                     (options.solver == PlaneModeOptions::Solver::automatic && (n <= kDenseMaxDofs || every));
  if (dense || n <= 4) return dense_plane_modes(k, m, options);
  PlaneLanczos lanczos(k, m, plant.node_positions_m());
  return lanczos.run(options);
}

PlaneModes free_free_plane_modes(const PlantModel& plant, int count) {
  PlaneModeOptions o;
  if (count >= 0) o.max_elastic = std::max(0, count - 2);
  PlaneModes out = free_free_plane_modes(plant, o);
  if (count >= 0 && count < out.omega_rad_per_s.size()) {
    out.omega_rad_per_s.conservativeResize(count);
    out.shapes.conservativeResize(Eigen::NoChange, count);
  }
  return out;
}

}  // namespace ambdiag
