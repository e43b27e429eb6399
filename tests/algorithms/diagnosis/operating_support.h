// Simulated runs of a pump under real operating conditions for the
// operating-reference tests: the plant model at a given speed with its
// fluid-seal links (kind seal, balance_piston) drifted, optionally a fault,
// plus complex Gaussian noise with the shared files' sigma (1 % of each
// entry's RMS). The synthesis is the default modal one of model_frf_like,
// not the detection's Krylov one, so the model is not exactly the truth.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "ambdiag/algorithms/diagnosis/fault_models.h"
#include "ambdiag/algorithms/model/frf_compare.h"
#include "diagnosis_support.h"

namespace ambdiag::testing {

// Drift of the fluid-seal coefficients: factor (1 + common) (1 + own_k).
struct SealDrift {
  double common = 0.0;
  std::vector<double> own;  // per fluid link in plant order; empty: none
};

inline PlantModel drifted(const PlantModel& plant, const SealDrift& drift) {
  PlantModel p = plant;
  size_t k = 0;
  for (auto& link : p.links) {
    if (link.kind != "seal" && link.kind != "balance_piston") continue;
    const double own = k < drift.own.size() ? drift.own[k] : 0.0;
    scale_link(link, (1.0 + drift.common) * (1.0 + own));
    ++k;
  }
  return p;
}

// One run of `truth` (the plant, drifted and possibly faulty) at speed_rpm,
// on the grid and entries of `like`, with its sigma and noise.
inline FrfData simulate_run(const PlantModel& truth, const FrfData& like, double speed_rpm, std::mt19937_64& rng,
                            const FrfSynthesisOptions& synthesis = {FrfMethod::modal}) {
  FrfData skeleton = like;
  skeleton.speed_rpm = speed_rpm;
  FrfData clean = model_frf_like(truth, skeleton, synthesis);
  clean.metadata = like.metadata;
  clean.set_meta("speed_rpm", std::to_string(speed_rpm));
  clean.speed_rpm = speed_rpm;
  return with_noise(clean, like, rng);
}

// Normal operation: speed 2950 x (1 + U(-speed_span, +speed_span)), a common
// seal drift N(0, common_sd) and each link's own N(0, own_sd).
struct Operation {
  double speed_span = 0.03, common_sd = 0.02, own_sd = 0.005;
  double nominal_rpm = 2950.0;
};

inline FrfData healthy_run(const PlantModel& plant, const FrfData& like, const Operation& op, std::mt19937_64& rng,
                           const FrfSynthesisOptions& synthesis = {FrfMethod::modal}) {
  std::uniform_real_distribution<double> u(-op.speed_span, op.speed_span);
  std::normal_distribution<double> n(0.0, 1.0);
  SealDrift d;
  d.common = op.common_sd * n(rng);
  for (const auto& l : plant.links)
    if (l.kind == "seal" || l.kind == "balance_piston") d.own.push_back(op.own_sd * n(rng));
  const double rpm = op.nominal_rpm * (1.0 + u(rng));
  return simulate_run(drifted(plant, d), like, rpm, rng, synthesis);
}

inline FrfData shared_like() { return read_frf_csv(data_file("reference_pump/frf_ref_1.csv").string()); }

}  // namespace ambdiag::testing
