// Modal features as symptoms (the paper's Table 4): natural frequencies and
// damping ratios identified from each reference run (rational_fit.h),
// paired across runs (same direction, nearest within 5 %), their mean and
// variance, and the normalised shift of a measured run's modes (paired
// globally, closest first, within 30 %: a fault moves modes far more than
// run-to-run scatter does).
//
// Variance of a feature: the identification's own standard deviation (ML,
// from thousands of lines, well determined) scaled to the between-run
// scatter when that is significantly larger: with n runs, sample variance
// s^2 and mean ML variance q, (n - 1) s^2 / q is chi2(n - 1) if the runs
// differ by estimation noise only; kappa = s^2 / q when that test rejects
// at alpha_scatter, else 1 (n = 5 cannot estimate a covariance matrix of
// ~20 features, so features are taken as independent: a diagonal
// Hotelling / chi2 statistic).
//   z = (x - mean) / sqrt(kappa (q_x + q / n)),  T = sum z^2 ~ chi2(2 K)
// over the K reference modes found in the measured run.
#pragma once

#include <string>
#include <vector>

#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/core/frf_data.h"

namespace ambdiag {

struct ModalFeatureStats {
  std::string direction;  // "radial" or "axial"
  double f_hz = 0.0, zeta = 0.0;          // means over the runs
  double f_var = 0.0, zeta_var = 0.0;     // of one run (kappa q)
  double f_kappa = 1.0, zeta_kappa = 1.0;
};

struct ModalFeatureReference {
  int runs = 0;
  std::vector<ModalFeatureStats> modes;  // found in every run, ascending f
};

struct ModalFeatureShift {
  int reference_mode = -1;  // into ModalFeatureReference::modes; -1: a new mode
  double f_hz = 0.0, zeta = 0.0;
  double z_f = 0.0, z_zeta = 0.0;
};

struct ModalFeatureTest {
  double statistic = 0.0, threshold = 0.0, dof = 0.0, p_value = 1.0;
  bool detected = false;
  std::vector<ModalFeatureShift> shifts;  // paired modes and new modes
  std::vector<int> missing;               // reference modes not found
};

// Throws InputError if fewer than two runs are given.
ModalFeatureReference modal_feature_reference(const std::vector<FrfData>& runs, const RationalFitOptions& fit = {},
                                              double alpha_scatter = 0.01);
ModalFeatureTest modal_feature_test(const ModalFeatureReference& ref, const FrfData& measured, double alpha,
                                    const RationalFitOptions& fit = {});

}  // namespace ambdiag
