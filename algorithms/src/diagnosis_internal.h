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
};

struct Aligned {
  std::vector<double> freq_hz;
  double speed_rpm = 0.0;
  std::vector<AlignedEntry> entries;
  int values() const;  // complex values (entries x lines)
};

Aligned align(const ReferenceStatistics& ref, const FrfData& measured);

// Detection test, symptoms and the pattern isolation; fills those fields.
void detect(const Aligned& a, const DiagnosisOptions& options, DiagnosisResult& result);

}  // namespace ambdiag::diagnosis_detail
