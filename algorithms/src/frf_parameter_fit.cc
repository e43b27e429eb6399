#include "ambdiag/algorithms/frf_parameter_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

using Values = std::vector<std::vector<std::complex<double>>>;

// Real residual vector (re, im per value).
Eigen::VectorXd residual(const FrfFitTarget& t, const Values& model) {
  Eigen::VectorXd r(2 * t.values());
  Eigen::Index k = 0;
  for (size_t e = 0; e < t.measured.size(); ++e) {
    for (size_t l = 0; l < t.measured[e].size(); ++l) {
      std::complex<double> d = model[e][l] - t.measured[e][l];
      if (!t.offset.empty()) d += t.offset[e][l];
      d *= t.weight[e][l];
      r[k++] = d.real();
      r[k++] = d.imag();
    }
  }
  return r;
}

void check_shape(const FrfFitTarget& t, const Values& model) {
  if (model.size() != t.measured.size()) throw std::logic_error("fit_parameters: model returned the wrong number of entries");
  for (size_t e = 0; e < model.size(); ++e)
    if (model[e].size() != t.measured[e].size()) throw std::logic_error("fit_parameters: model returned the wrong number of lines");
}

}  // namespace

int FrfFitTarget::values() const {
  int n = 0;
  for (const auto& e : measured) n += static_cast<int>(e.size());
  return n;
}

bool ParameterFitOptions::is_valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (start.size() == 0) return fail("parameter fit: no parameters");
  if (lower.size() != start.size() || upper.size() != start.size()) return fail("parameter fit: bounds and start differ in size");
  if (fd_step.size() != 0 && fd_step.size() != start.size()) return fail("parameter fit: fd_step has the wrong size");
  for (Eigen::Index i = 0; i < start.size(); ++i) {
    if (!(lower[i] < upper[i])) return fail("parameter fit: lower bound " + std::to_string(i) + " not below upper");
    if (!(start[i] >= lower[i] && start[i] <= upper[i])) return fail("parameter fit: start " + std::to_string(i) + " outside bounds");
  }
  if (max_iterations < 1) return fail("parameter fit: max_iterations must be >= 1");
  return true;
}

double fit_chi2(const FrfFitTarget& target, const Values& model) {
  check_shape(target, model);
  return residual(target, model).squaredNorm();
}

ParameterFitResult fit_parameters(const FrfModelFunction& model, const FrfFitTarget& target, const ParameterFitOptions& opt) {
  std::string why;
  if (!opt.is_valid(&why)) throw InputError(why);
  const Eigen::Index n = opt.start.size();
  const Eigen::VectorXd range = opt.upper - opt.lower;
  const Eigen::VectorXd step = opt.fd_step.size() ? opt.fd_step : Eigen::VectorXd(1e-4 * range);

  ParameterFitResult res;
  auto eval = [&](const Eigen::VectorXd& p) {
    Values v = model(p);
    ++res.evaluations;
    check_shape(target, v);
    return residual(target, v);
  };
  Eigen::VectorXd p = opt.start;
  Eigen::VectorXd r = eval(p);
  double chi2 = r.squaredNorm();
  res.chi2_start = chi2;
  double lambda = 1e-3;
  Eigen::MatrixXd jac(r.size(), n);

  auto difference_jacobian = [&]() {
    for (Eigen::Index j = 0; j < n; ++j) {
      Eigen::VectorXd q = p;
      double h = step[j];
      if (q[j] + h > opt.upper[j]) h = -h;  // step back into the box at the upper bound
      q[j] += h;
      jac.col(j) = (eval(q) - r) / h;
    }
  };
  // Broyden: J += (dr - J dp) dp^T / |dp|^2 for any evaluated step dp.
  auto secant_update = [&](const Eigen::VectorXd& dp, const Eigen::VectorXd& dr) {
    const double d2 = dp.squaredNorm();
    if (d2 > 0.0) jac += (dr - jac * dp) * dp.transpose() / d2;
  };

  if (opt.jacobian0.size() != 0) {
    if (opt.jacobian0.rows() != r.size() || opt.jacobian0.cols() != n)
      throw InputError("parameter fit: jacobian0 must be (2 x values) x parameters");
    jac = opt.jacobian0;
  } else {
    difference_jacobian();
  }
  for (res.iterations = 0; res.iterations < opt.max_iterations; ++res.iterations) {
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    bool improved = false, small_step = false;
    for (int tries = 0; tries < (opt.broyden ? 6 : 12); ++tries) {
      Eigen::MatrixXd a = jtj;
      for (Eigen::Index j = 0; j < n; ++j) a(j, j) += lambda * std::max(jtj(j, j), 1e-30);
      const Eigen::VectorXd dp_try = -a.ldlt().solve(g);
      const Eigen::VectorXd q = (p + dp_try).cwiseMax(opt.lower).cwiseMin(opt.upper);
      const Eigen::VectorXd dp = q - p;
      small_step = (dp.cwiseAbs().array() <= opt.step_tolerance * range.array()).all();
      if (small_step) break;  // converged, or pinned at a bound
      const Eigen::VectorXd rq = eval(q);
      if (opt.broyden) secant_update(dp, rq - r);
      const double c = rq.squaredNorm();
      if (c < chi2) {
        const double gain = (chi2 - c) / std::max(chi2, 1e-300);
        p = q;
        r = rq;
        chi2 = c;
        lambda = std::max(lambda * 0.2, 1e-9);
        improved = true;
        if (gain < opt.rel_tolerance) {
          res.converged = true;
          res.stop_reason = "relative decrease below tolerance";
        }
        break;
      }
      lambda *= 10.0;
    }
    if (small_step) {
      res.converged = true;
      res.stop_reason = "step below tolerance (minimum or bound)";
      break;
    }
    if (!improved) {
      res.converged = true;
      res.stop_reason = "no further decrease";
      break;
    }
    if (res.converged) break;
    if (!opt.broyden) difference_jacobian();
  }
  if (!res.converged) res.stop_reason = "iteration limit";
  if (!opt.broyden) difference_jacobian();  // at the solution
  const Eigen::MatrixXd jtj = jac.transpose() * jac;
  // Each real residual component has variance 1/2 when the weights are
  // 1 / sigma of the complex value, so Cov = (J^T J)^-1 / 2.
  const double dof = std::max<double>(0.5 * static_cast<double>(r.size()) - 0.5 * static_cast<double>(n), 1.0);
  const double scale = 0.5 * std::max(1.0, chi2 / dof);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(jtj);
  res.covariance = lu.isInvertible() ? Eigen::MatrixXd(scale * lu.inverse()) : Eigen::MatrixXd::Zero(n, n);
  res.jacobian = jac;
  res.p = p;
  res.chi2 = chi2;
  return res;
}

}  // namespace ambdiag
