// The one Levenberg-Marquardt (numerics/least_squares.h) against closed
// forms: a linear model's least-squares solution and covariance, and the
// Monte-Carlo spread of a resonance's fitted parameters against the
// standard deviations the fit reports.
#include "ambdiag/algorithms/numerics/least_squares.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "ambdiag/core/error.h"

namespace ambdiag {
namespace {

using cd = std::complex<double>;

// A single-degree-of-freedom compliance 1 / (k - m w^2 + j c w) on 60 lines
// around its resonance (k = 1e6 N/m, m = 10 kg: 50.3 Hz).
struct Resonance {
  std::vector<double> omega;
  Resonance() {
    for (int l = 0; l < 60; ++l) omega.push_back(2.0 * M_PI * (30.0 + l * 0.7));
  }
  std::vector<cd> h(double k, double m, double c) const {
    std::vector<cd> out;
    for (double w : omega) out.push_back(1.0 / cd(k - m * w * w, c * w));
    return out;
  }
};

std::vector<cd> noisy(const std::vector<cd>& h, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma / std::sqrt(2.0));  // complex noise of std sigma
  std::vector<cd> out = h;
  for (auto& v : out) v += cd(n(rng), n(rng));
  return out;
}

TEST(LeastSquares, LinearModelGivesTheClosedFormSolutionAndCovariance) {
  // m_k(x) = a_k0 x0 + a_k1 x1 with complex a, measured with noise sigma.
  const int n = 40;
  const double sigma = 0.05;
  std::vector<cd> a0, a1, y;
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < n; ++k) {
    a0.emplace_back(g(rng), g(rng));
    a1.emplace_back(std::cos(0.1 * k), std::sin(0.3 * k));
    y.push_back(a0.back() * 1.5 - a1.back() * 0.7);
  }
  y = noisy(y, sigma, 9);
  auto residual = [&](const std::vector<double>& x) {
    std::vector<cd> r;
    for (int k = 0; k < n; ++k) r.push_back((a0[k] * x[0] + a1[k] * x[1] - y[k]) / sigma);
    return r;
  };
  LeastSquaresOptions o;
  o.noise = NoiseLevel::known;
  o.rel_tolerance = 1e-12;
  const LeastSquaresResult r = fit_least_squares(residual, {{"x0", 0.0, -10.0, 10.0}, {"x1", 0.0, -10.0, 10.0}}, o);

  Eigen::MatrixXd j(2 * n, 2);
  Eigen::VectorXd yr(2 * n);
  for (int k = 0; k < n; ++k) {
    j.row(2 * k) << a0[k].real() / sigma, a1[k].real() / sigma;
    j.row(2 * k + 1) << a0[k].imag() / sigma, a1[k].imag() / sigma;
    yr(2 * k) = y[k].real() / sigma;
    yr(2 * k + 1) = y[k].imag() / sigma;
  }
  const Eigen::Vector2d x_ls = (j.transpose() * j).ldlt().solve(j.transpose() * yr);
  EXPECT_NEAR(r.x[0], x_ls[0], 1e-6);
  EXPECT_NEAR(r.x[1], x_ls[1], 1e-6);
  // Known noise: each real component has variance 1/2, so Cov = (J^T J)^-1 / 2,
  // inflated by chi2 / dof only when the misfit exceeds the noise.
  const double dof = n - 1.0;
  const Eigen::Matrix2d cov = 0.5 * std::max(1.0, r.chi2 / dof) * (j.transpose() * j).inverse();
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b) EXPECT_NEAR(r.covariance(a, b), cov(a, b), 1e-4 * std::abs(cov(a, a))) << a << b;
  EXPECT_NEAR(r.sd[0], std::sqrt(cov(0, 0)), 1e-4 * std::sqrt(cov(0, 0)));
}

// Over 200 noise draws the fitted k, m, c scatter as the reported sd says:
// the sample standard deviation within 20 % of the mean reported sd (the
// sample sd of 200 normal draws has a relative error of 5 %; the model is
// mildly nonlinear at this noise level).
void check_spread(NoiseLevel noise) {
  const Resonance res;
  const std::vector<cd> truth = res.h(1e6, 10.0, 200.0);
  double peak = 0.0;
  for (const auto& v : truth) peak = std::max(peak, std::abs(v));
  const double sigma = 0.01 * peak;
  const int draws = 200;
  std::vector<std::vector<double>> est(3), sd(3);
  for (int d = 0; d < draws; ++d) {
    const std::vector<cd> meas = noisy(truth, sigma, 100 + d);
    auto residual = [&](const std::vector<double>& x) {
      const std::vector<cd> h = res.h(x[0], x[1], x[2]);
      std::vector<cd> r(h.size());
      for (size_t l = 0; l < h.size(); ++l) r[l] = (h[l] - meas[l]) / sigma;
      return r;
    };
    LeastSquaresOptions o;
    o.noise = noise;
    o.max_iterations = 60;
    o.rel_tolerance = 1e-10;
    const LeastSquaresResult r =
        fit_least_squares(residual, {{"k", 0.9e6, 1e5, 1e7, 1e4}, {"m", 9.5, 1.0, 100.0, 0.1}, {"c", 300.0, 1.0, 1e4, 10.0}}, o);
    ASSERT_TRUE(r.converged) << r.stop_reason;
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE(std::isfinite(r.sd[static_cast<size_t>(i)]));
      est[static_cast<size_t>(i)].push_back(r.x[static_cast<size_t>(i)]);
      sd[static_cast<size_t>(i)].push_back(r.sd[static_cast<size_t>(i)]);
    }
  }
  const double want[3] = {1e6, 10.0, 200.0};
  for (size_t i = 0; i < 3; ++i) {
    double mean = 0.0, var = 0.0, sd_mean = 0.0;
    for (int d = 0; d < draws; ++d) mean += est[i][static_cast<size_t>(d)] / draws, sd_mean += sd[i][static_cast<size_t>(d)] / draws;
    for (int d = 0; d < draws; ++d) var += std::pow(est[i][static_cast<size_t>(d)] - mean, 2) / (draws - 1);
    EXPECT_NEAR(std::sqrt(var) / sd_mean, 1.0, 0.2) << i;
    EXPECT_NEAR(mean, want[i], 4.0 * sd_mean / std::sqrt(draws)) << i;  // unbiased to within its standard error
  }
}

TEST(LeastSquares, ReportedSdMatchesTheScatterWithKnownNoise) { check_spread(NoiseLevel::known); }
TEST(LeastSquares, ReportedSdMatchesTheScatterWithEstimatedNoise) { check_spread(NoiseLevel::estimated); }

// Broyden's secant updates, as the diagnosis uses them (one fault
// parameter, from a start near the optimum: the secant method on the
// residual vector), end where a difference Jacobian per iteration ends, for
// fewer evaluations. (With several correlated parameters, such as k and m
// of one resonance, Broyden's Jacobian can stall far from the optimum; the
// diagnosis fits those only from a linearised start.)
TEST(LeastSquares, BroydenUpdatesOnOneParameterReachTheSameFit) {
  const Resonance res;
  const std::vector<cd> truth = res.h(1e6, 10.0, 200.0);
  double peak = 0.0;
  for (const auto& v : truth) peak = std::max(peak, std::abs(v));
  const double sigma = 0.01 * peak;
  for (unsigned d = 0; d < 10; ++d) {
    const std::vector<cd> meas = noisy(truth, sigma, 500 + d);
    auto residual = [&](const std::vector<double>& x) {
      const std::vector<cd> h = res.h(x[0], 10.0, 200.0);
      std::vector<cd> r(h.size());
      for (size_t l = 0; l < h.size(); ++l) r[l] = (h[l] - meas[l]) / sigma;
      return r;
    };
    const std::vector<FitParameter> params{{"k", 1.02e6, 1e5, 1e7, 1e4}};
    LeastSquaresOptions o;
    o.noise = NoiseLevel::known;
    o.max_iterations = 60;
    o.rel_tolerance = 1e-10;
    const LeastSquaresResult diff = fit_least_squares(residual, params, o);
    o.broyden = true;
    const LeastSquaresResult secant = fit_least_squares(residual, params, o);
    EXPECT_NEAR(secant.x[0], diff.x[0], 0.05 * diff.sd[0]) << d;
    EXPECT_NEAR(secant.x[0], 1e6, 4.0 * diff.sd[0]) << d;
    EXPECT_LT(secant.evaluations, diff.evaluations) << d;
  }
}

TEST(LeastSquares, EndsAtABoundWithoutAnSd) {
  const Resonance res;
  const std::vector<cd> meas = res.h(1e6, 10.0, 200.0);
  auto residual = [&](const std::vector<double>& x) {
    const std::vector<cd> h = res.h(x[0], 10.0, 200.0);
    std::vector<cd> r(h.size());
    for (size_t l = 0; l < h.size(); ++l) r[l] = (h[l] - meas[l]) / 1e-9;
    return r;
  };
  const LeastSquaresResult r = fit_least_squares(residual, {{"k", 0.7e6, 0.5e6, 0.8e6, 1e4}});
  EXPECT_DOUBLE_EQ(r.x[0], 0.8e6);  // the truth (1e6) is outside
  EXPECT_TRUE(std::isnan(r.sd[0]));
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.chi2, r.chi2_start);
}

TEST(LeastSquares, NoParametersJustEvaluates) {
  const LeastSquaresResult r = fit_least_squares([](const std::vector<double>&) { return std::vector<cd>{{3.0, 4.0}}; }, {});
  EXPECT_DOUBLE_EQ(r.chi2, 25.0);
  EXPECT_EQ(r.evaluations, 1);
}

TEST(LeastSquares, RefusesBadParametersNamingThem) {
  auto residual = [](const std::vector<double>& x) { return std::vector<cd>{{x[0], 0.0}}; };
  try {
    fit_least_squares(residual, {{"gain", 1.0, 2.0, 0.5}});
    FAIL() << "lower above upper accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gain"), std::string::npos) << e.what();
  }
  EXPECT_THROW(fit_least_squares(residual, {{"gain", 1.0, 0.0, 2.0, 0.0}}), InputError);
  LeastSquaresOptions o;
  o.jacobian0 = Eigen::MatrixXd::Zero(3, 1);  // the residual has 2 real components
  EXPECT_THROW(fit_least_squares(residual, {{"gain", 1.0, 0.0, 2.0}}, o), InputError);
}

}  // namespace
}  // namespace ambdiag
