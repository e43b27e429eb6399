// Weighted Gram matrices of a common complex basis for many FRF entries at
// once (general weights, one per line and entry).
#include <Eigen/Dense>
#include <algorithm>
#include <utility>
#include <vector>

#include "fit_data.h"

namespace ambdiag::detail {

namespace {

// Lines per block: the per-line products of a block stay in cache.
constexpr Eigen::Index kBlockLines = 128;

}  // namespace

Eigen::Index packed_size(Eigen::Index n, Eigen::Index first_col) { return n * (n + 1) / 2 - first_col * (first_col + 1) / 2; }

Eigen::MatrixXd entry_gram_pairs(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w2, const std::vector<std::pair<int, int>>& pairs) {
  const Eigen::Index L = x.rows(), E = w2.cols(), np = static_cast<Eigen::Index>(pairs.size());
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(E, np);
  if (np == 0) return out;
  const Eigen::MatrixXd xr = x.real(), xi = x.imag();
  Eigen::MatrixXd prod(std::min(L, kBlockLines), np);
  for (Eigen::Index l0 = 0; l0 < L; l0 += kBlockLines) {
    const Eigen::Index lc = std::min(kBlockLines, L - l0);
    for (Eigen::Index k = 0; k < np; ++k) {
      const auto [i, j] = pairs[static_cast<size_t>(k)];
      prod.col(k).head(lc) = xr.col(i).segment(l0, lc).cwiseProduct(xr.col(j).segment(l0, lc)) +
                             xi.col(i).segment(l0, lc).cwiseProduct(xi.col(j).segment(l0, lc));
    }
    out.noalias() += w2.middleRows(l0, lc).transpose() * prod.topRows(lc);
  }
  return out;
}

Eigen::MatrixXd entry_grams(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w2, Eigen::Index first_col) {
  std::vector<std::pair<int, int>> pairs;
  for (int j = static_cast<int>(first_col); j < x.cols(); ++j)
    for (int i = 0; i <= j; ++i) pairs.emplace_back(i, j);
  return entry_gram_pairs(x, w2, pairs);
}

Eigen::MatrixXd entry_grams_imag(const Eigen::MatrixXcd& x, const Eigen::MatrixXd& w) {
  const Eigen::Index L = x.rows(), n = x.cols(), E = w.cols(), np = n * (n - 1) / 2;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(E, np);
  if (np == 0) return out;
  const Eigen::MatrixXd xr = x.real(), xi = x.imag();
  Eigen::MatrixXd prod(std::min(L, kBlockLines), np);
  for (Eigen::Index l0 = 0; l0 < L; l0 += kBlockLines) {
    const Eigen::Index lc = std::min(kBlockLines, L - l0);
    Eigen::Index k = 0;
    for (Eigen::Index j = 1; j < n; ++j)
      for (Eigen::Index i = 0; i < j; ++i, ++k)
        prod.col(k).head(lc) = xr.col(i).segment(l0, lc).cwiseProduct(xi.col(j).segment(l0, lc)) -
                               xi.col(i).segment(l0, lc).cwiseProduct(xr.col(j).segment(l0, lc));
    out.noalias() += w.middleRows(l0, lc).transpose() * prod.topRows(lc);
  }
  return out;
}

Eigen::MatrixXd unpack_gram(const Eigen::Ref<const Eigen::VectorXd>& packed, Eigen::Index n, Eigen::Index first_col) {
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(n, n);
  Eigen::Index k = 0;
  for (Eigen::Index j = first_col; j < n; ++j)
    for (Eigen::Index i = 0; i <= j; ++i, ++k) g(i, j) = g(j, i) = packed(k);
  return g;
}

EntrySystems solve_entries(const FitData& data, const Eigen::MatrixXcd& phi) {
  const int E = data.entries();
  const Eigen::Index nc = phi.cols();
  const Eigen::MatrixXd w2 = data.weight.cwiseAbs2();
  const Eigen::MatrixXd grams = entry_grams(phi, w2);
  // Right-hand sides Re(phi^H diag(w_e^2) h_e) of all entries in one product.
  const Eigen::MatrixXd pr = phi.real(), pi = phi.imag();
  const Eigen::MatrixXd rhs = pr.transpose() * w2.cwiseProduct(data.h.real()) + pi.transpose() * w2.cwiseProduct(data.h.imag());
  EntrySystems out;
  out.coef.resize(nc, E);
  out.gram.reserve(static_cast<size_t>(E));
  for (int e = 0; e < E; ++e) {
    out.gram.emplace_back(GramSolver::FromGram{}, unpack_gram(grams.row(e).transpose(), nc));
    out.coef.col(e) = out.gram.back().solve(rhs.col(e));
  }
  // Weighted residual computed directly (not as |y|^2 - c^T b, which cancels
  // digits at a high signal-to-noise ratio).
  out.wresid.resize(data.lines(), E);
  out.wresid.real() = data.weight.cwiseProduct(pr * out.coef - data.h.real());
  out.wresid.imag() = data.weight.cwiseProduct(pi * out.coef - data.h.imag());
  out.cost = out.wresid.squaredNorm();
  return out;
}

}  // namespace ambdiag::detail
