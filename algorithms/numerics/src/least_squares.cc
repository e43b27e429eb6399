#include "ambdiag/algorithms/numerics/least_squares.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

Eigen::VectorXd stack(const std::vector<std::complex<double>>& r) {
  Eigen::VectorXd v(2 * static_cast<Eigen::Index>(r.size()));
  for (size_t k = 0; k < r.size(); ++k) {
    v(2 * static_cast<Eigen::Index>(k)) = r[k].real();
    v(2 * static_cast<Eigen::Index>(k) + 1) = r[k].imag();
  }
  return v;
}

void check(const std::vector<FitParameter>& params) {
  for (const auto& p : params) {
    if (!(p.lower <= p.upper)) throw InputError("least-squares fit: parameter " + p.name + ": lower bound above upper");
    if (!(p.scale > 0.0) || !std::isfinite(p.scale)) throw InputError("least-squares fit: parameter " + p.name + ": scale must be positive");
  }
}

}  // namespace

double chi2_of(const std::vector<std::complex<double>>& r) {
  double s = 0.0;
  for (const auto& v : r) s += std::norm(v);
  return s;
}

LeastSquaresResult fit_least_squares(const ResidualFunction& residual, const std::vector<FitParameter>& params,
                                     const LeastSquaresOptions& opt) {
  check(params);
  const Eigen::Index n = static_cast<Eigen::Index>(params.size());
  Eigen::VectorXd lower(n), upper(n), scale(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const FitParameter& p = params[static_cast<size_t>(i)];
    lower[i] = p.lower, upper[i] = p.upper, scale[i] = p.scale;
  }
  const Eigen::VectorXd range = upper - lower;

  LeastSquaresResult res;
  std::vector<double> xv(params.size());
  auto eval = [&](const Eigen::VectorXd& x) {
    for (size_t i = 0; i < xv.size(); ++i) xv[i] = x[static_cast<Eigen::Index>(i)];
    ++res.evaluations;
    return stack(residual(xv));
  };
  Eigen::VectorXd x(n);
  for (Eigen::Index i = 0; i < n; ++i) x[i] = std::clamp(params[static_cast<size_t>(i)].initial, lower[i], upper[i]);
  Eigen::VectorXd r = eval(x);
  double chi2 = r.squaredNorm();
  res.chi2_start = chi2;
  res.x.assign(x.data(), x.data() + n);
  res.chi2 = chi2;
  if (n == 0) {
    res.stop_reason = "no parameters";
    return res;
  }

  Eigen::MatrixXd jac(r.size(), n);
  auto difference_jacobian = [&]() {
    for (Eigen::Index j = 0; j < n; ++j) {
      Eigen::VectorXd q = x;
      double h = opt.fd_step * scale[j];
      if (q[j] + h > upper[j]) h = -h;  // step back into the box at the upper bound
      q[j] += h;
      jac.col(j) = (eval(q) - r) / h;
    }
  };
  // Broyden: J += (dr - J dx) dx^T / |dx|^2 for any evaluated step dx.
  auto secant_update = [&](const Eigen::VectorXd& dx, const Eigen::VectorXd& dr) {
    const double d2 = dx.squaredNorm();
    if (d2 > 0.0) jac += (dr - jac * dx) * dx.transpose() / d2;
  };
  if (opt.jacobian0.size() != 0) {
    if (opt.jacobian0.rows() != r.size() || opt.jacobian0.cols() != n)
      throw InputError("least-squares fit: jacobian0 must be (2 x values) x parameters");
    jac = opt.jacobian0;
  } else {
    difference_jacobian();
  }

  const DampingSchedule& damp = opt.damping;
  double lambda = 1e-3;
  for (int it = 0; it < opt.max_iterations; ++it) {
    res.iterations = it + 1;
    if (it > 0 && !opt.broyden) difference_jacobian();
    // Normal equations in the scaled coordinates u = x / scale.
    const Eigen::MatrixXd js = jac * scale.asDiagonal();
    const Eigen::MatrixXd a = js.transpose() * js;
    const Eigen::VectorXd g = js.transpose() * r;
    bool improved = false, small_step = false;
    for (int rejected = 0; rejected < damp.max_rejections && lambda < damp.max_lambda; ++rejected) {
      Eigen::MatrixXd damped = a;
      for (Eigen::Index j = 0; j < n; ++j) damped(j, j) += lambda * std::max(a(j, j), 1e-12);
      const Eigen::VectorXd du = damped.ldlt().solve(-g);
      const Eigen::VectorXd q = (x + scale.cwiseProduct(du)).cwiseMax(lower).cwiseMin(upper);
      const Eigen::VectorXd dx = q - x;
      small_step = (dx.cwiseAbs().array() <= opt.step_tolerance * range.array()).all();
      if (small_step) break;  // converged, or pinned at a bound
      const Eigen::VectorXd rq = eval(q);
      if (opt.broyden) secant_update(dx, rq - r);
      const double c = rq.squaredNorm();
      if (c < chi2) {
        const double gain = (chi2 - c) / std::max(chi2, 1e-300);
        x = q;
        r = rq;
        chi2 = c;
        lambda = std::max(lambda * damp.shrink, 1e-9);
        improved = true;
        if (gain < opt.rel_tolerance) {
          res.converged = true;
          res.stop_reason = "relative decrease below tolerance";
        }
        break;
      }
      lambda *= damp.grow;
    }
    if (small_step) {
      res.converged = true;
      res.stop_reason = "step below tolerance (minimum or bound)";
      break;
    }
    if (!improved) {
      res.converged = true;
      res.stop_reason = "no step lowers chi2";
      break;
    }
    if (res.converged) break;
  }
  if (!res.converged) res.stop_reason = "iteration limit";

  const Eigen::MatrixXd jtj = jac.transpose() * jac;
  const double real_values = static_cast<double>(r.size());
  double factor = 0.0;
  if (opt.noise == NoiseLevel::known) {
    const double dof = std::max(0.5 * real_values - 0.5 * static_cast<double>(n), 1.0);
    factor = 0.5 * std::max(1.0, chi2 / dof);
  } else {
    factor = chi2 / std::max(1.0, real_values - static_cast<double>(n));
  }
  Eigen::FullPivLU<Eigen::MatrixXd> lu(jtj);
  res.covariance = lu.isInvertible() ? Eigen::MatrixXd(factor * lu.inverse()) : Eigen::MatrixXd::Zero(n, n);
  res.jacobian = jac;
  res.x.assign(x.data(), x.data() + n);
  res.chi2 = chi2;
  res.sd.assign(params.size(), std::numeric_limits<double>::quiet_NaN());
  for (Eigen::Index i = 0; i < n; ++i) {
    const bool at_bound = x[i] <= lower[i] || x[i] >= upper[i];
    if (!at_bound && res.covariance(i, i) > 0.0) res.sd[static_cast<size_t>(i)] = std::sqrt(res.covariance(i, i));
  }
  return res;
}

}  // namespace ambdiag
