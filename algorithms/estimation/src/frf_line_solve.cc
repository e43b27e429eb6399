// The per-line instrumental-variable solve shared by the periodic
// estimators, and the assembly of lines into an FrfData.
#include <algorithm>
#include <cmath>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag::frf_estimation {

double row_scaled_rcond(const Eigen::MatrixXcd& a) {
  Eigen::MatrixXcd s = a;
  for (Eigen::Index i = 0; i < s.rows(); ++i) {
    const double n = s.row(i).norm();
    if (n == 0.0) return 0.0;
    s.row(i) /= n;
  }
  const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXcd>(s).singularValues();
  return sv(0) > 0.0 ? sv(sv.size() - 1) / sv(0) : 0.0;
}

LineSolution solve_line(const std::vector<Experiment>& experiments, int n_out, int n_in) {
  LineSolution sol;
  const auto p = static_cast<Eigen::Index>(experiments.size());
  if (p < n_in) return sol;
  Eigen::MatrixXcd x(n_out, p), f(n_in, p), r(n_in, p);
  bool with_cov = true;
  for (Eigen::Index k = 0; k < p; ++k) {
    const Experiment& e = experiments[static_cast<size_t>(k)];
    x.col(k) = e.z.head(n_out);
    f.col(k) = e.z.tail(n_in);
    r.col(k) = e.r;
    with_cov = with_cov && e.cov.size() > 0;
  }
  const Eigen::MatrixXcd s_fr = f * r.adjoint();
  const Eigen::FullPivLU<Eigen::MatrixXcd> lu(s_fr);
  sol.rcond = row_scaled_rcond(f);
  if (sol.rcond == 0.0 || lu.rank() < n_in) {
    sol.rcond = 0.0;
    return sol;
  }
  const Eigen::MatrixXcd s_fr_inv = lu.inverse();
  sol.h = x * r.adjoint() * s_fr_inv;
  if (!with_cov) return sol;

  // (2): g_k = r_k^H S_fr^-1; the residual of output o is a^T z with
  // a = [unit_o; -H(o,:)^T], so var(e_k[o]) = a^T C_k conj(a).
  const Eigen::MatrixXcd g = r.adjoint() * s_fr_inv;  // p x n_in
  sol.sigma = Eigen::MatrixXd::Zero(n_out, n_in);
  Eigen::VectorXcd a(n_out + n_in);
  for (int o = 0; o < n_out; ++o) {
    a.setZero();
    a(o) = 1.0;
    a.tail(n_in) = -sol.h.row(o).transpose();
    for (Eigen::Index k = 0; k < p; ++k) {
      const Eigen::MatrixXcd& c = experiments[static_cast<size_t>(k)].cov;
      const double var_e = std::max(0.0, (a.transpose() * c * a.conjugate())(0, 0).real());
      sol.sigma.row(o) += var_e * g.row(k).cwiseAbs2();
    }
  }
  sol.sigma = sol.sigma.cwiseSqrt();
  return sol;
}

double coherence_from_sigma(std::complex<double> h, double sigma, double averages) {
  const double signal = std::norm(h), noise = averages * sigma * sigma;
  if (signal + noise == 0.0) return 0.0;
  return std::clamp(signal / (signal + noise), 0.0, 1.0);
}

FrfAssembler::FrfAssembler(const ChannelPlan& plan, bool with_sigma, bool with_coherence)
    : n_out_(plan.n_out()), n_in_(plan.n_in()), with_sigma_(with_sigma), with_coh_(with_coherence) {
  for (const auto& o : plan.outputs) {
    for (const auto& i : plan.inputs) {
      FrfEntry e;
      e.output = o;
      e.input = i;
      frf_.entries.push_back(std::move(e));
    }
  }
}

void FrfAssembler::add(double freq_hz, const Eigen::MatrixXcd& h, const Eigen::MatrixXd& sigma,
                       const Eigen::MatrixXd& coh) {
  frf_.freq_hz.push_back(freq_hz);
  for (int o = 0; o < n_out_; ++o) {
    for (int i = 0; i < n_in_; ++i) {
      FrfEntry& e = frf_.entries[static_cast<size_t>(o * n_in_ + i)];
      e.h.push_back(h(o, i));
      if (with_sigma_) e.sigma.push_back(sigma(o, i));
      if (with_coh_) e.coh.push_back(std::clamp(coh(o, i), 0.0, 1.0));
    }
  }
}

void FrfAssembler::drop(double freq_hz, const std::string& reason) {
  auto it = std::find_if(dropped_.begin(), dropped_.end(), [&](const auto& d) { return d.first == reason; });
  if (it == dropped_.end()) {
    dropped_.push_back({reason, {}});
    it = dropped_.end() - 1;
  }
  it->second.push_back(freq_hz);
}

void FrfAssembler::note_rcond(double freq_hz, double rcond, double warn_rcond) {
  if (rcond >= warn_rcond) return;
  poorly_conditioned_hz_.push_back(freq_hz);
  worst_rcond_ = std::min(worst_rcond_, rcond);
}

FrfData FrfAssembler::finish(std::vector<std::string>& warnings, long& dropped, const std::string& what) {
  for (const auto& [reason, lines] : dropped_) {
    warnings.push_back(describe_lines(lines) + " dropped: " + reason);
    dropped += static_cast<long>(lines.size());
  }
  if (!poorly_conditioned_hz_.empty()) {
    warnings.push_back(describe_lines(poorly_conditioned_hz_) +
                       " poorly conditioned (input spectra nearly dependent, reciprocal condition down to " +
                       format_number(worst_rcond_) + "): their sigma is large");
  }
  if (frf_.freq_hz.empty()) {
    std::string why = what + ": no line could be estimated";
    for (const auto& [reason, lines] : dropped_) why += "; " + describe_lines(lines) + ": " + reason;
    throw InputError(why);
  }
  return std::move(frf_);
}

}  // namespace ambdiag::frf_estimation
