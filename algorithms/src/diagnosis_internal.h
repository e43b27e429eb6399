// Private to the diagnosis: the measured FRF aligned with the reference
// statistics, entry by entry, with the variances the tests weight by.
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "ambdiag/algorithms/diagnosis.h"

namespace ambdiag::diagnosis_detail {

struct AlignedEntry {
  std::string output, input;
  std::vector<std::complex<double>> h;     // measured
  std::vector<std::complex<double>> mean;  // reference mean
  std::vector<double> var;                 // of H - mean: u + v
  // Moments of t = 2 |H - mean|^2 / var per line on the healthy machine:
  // 2 and 4 when var is known, more when u rests on a sigma estimated with
  // few degrees of freedom (align()).
  std::vector<double> t_mean;
  double t_var = 0.0;  // summed over the lines
};

struct Aligned {
  std::vector<double> freq_hz;
  double speed_rpm = 0.0;
  std::vector<AlignedEntry> entries;
  int values() const;  // complex values (entries x lines)
  double t_mean() const;  // expected detection statistic on the healthy machine
};

Aligned align(const ReferenceStatistics& ref, const FrfData& measured);

// Detection test, symptoms and the pattern isolation; fills those fields.
void detect(const Aligned& a, const DiagnosisOptions& options, DiagnosisResult& result);

}  // namespace ambdiag::diagnosis_detail
