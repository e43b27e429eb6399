// What the healthy machine looks like: statistics of several reference FRF
// measurements, so that detection thresholds come from measured scatter.
//
// Per entry e and line l, from n runs H_i with stated sigma_i (the files'
// sigma_ columns, complex standard deviation):
//   mean      m_el = (1/n) sum_i H_i
//   var_mean  v_el = kappa_e (1/n^2) sum_i sigma_i^2        (of the mean)
//   var_run   u_el = kappa_e (1/n) sum_i sigma_i^2          (of one new run)
// kappa_e scales the stated noise up to the between-run scatter when that is
// significantly larger: with s_el = sum_i |H_i - m|^2, the statistic
// S_e = sum_l 2 s_el / ((1/n) sum_i sigma_i^2) is chi2 with 2 (n-1) L degrees
// of freedom if the sigma columns are right. kappa_e = S_e / dof when S_e
// exceeds its 1 - alpha_scatter quantile, else 1: a few runs (n = 5 gives 8
// real degrees of freedom per line) never estimate a variance per line, but
// pooled over the L lines of an entry they test the stated sigma well.
// Without sigma columns, the per-line variance is the between-run scatter
// averaged over +-5 neighbouring lines (needs n >= 2).
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "ambdiag/core/frf_data.h"

namespace ambdiag {

struct ReferenceEntryStatistics {
  std::string output, input;
  std::vector<std::complex<double>> mean;
  std::vector<double> var_mean;  // variance of the mean, per line
  std::vector<double> var_run;   // variance of one run, per line
  double scatter_ratio = 1.0;    // S_e / dof: between-run scatter over stated noise
  double scatter_p = 1.0;        // upper-tail probability of S_e
  double kappa = 1.0;            // factor applied to the stated variance
  bool sigma_stated = true;      // false: variance from the between-run scatter
};

struct ReferenceStatistics {
  std::vector<double> freq_hz;
  double speed_rpm = 0.0;  // 0 when the files state none
  int runs = 0;
  std::vector<ReferenceEntryStatistics> entries;
  const ReferenceEntryStatistics* find(const std::string& output, const std::string& input) const;
};

struct ReferenceOptions {
  double alpha_scatter = 0.01;  // significance of "scatter exceeds sigma"
};

// Throws InputError if there are no runs, grids or speeds differ, entries
// differ between runs, or there is one run without sigma columns.
ReferenceStatistics reference_statistics(const std::vector<FrfData>& runs, const ReferenceOptions& options = {});

}  // namespace ambdiag
