// Recordings of the same machine at other speeds (issue 18: "where runs at
// more than one speed exist, use the speed dependence"). The explanation is
// chosen on the first recording; the others then judge it, because the
// physics differ in how they change with speed while one recording at one
// speed may not tell them apart:
//   gyroscopic moments      Ip Omega: fixed by the speed, no free law;
//   an added spinning mass  the same (its Ip), plus a mass that does not care;
//   seal cross-coupling     grows with speed (bulk-flow theory: k_xy = C Omega / 2,
//                           with C itself rising with the pressure drop ~ Omega^2),
//                           so its law k(Omega) = k0 (Omega / Omega0)^n is
//                           fitted, n in [0, 3], one n shared by the recordings;
//   housing, delay, sensor  none.
// The claim and each alternative are judged by a joint fit of their own
// parameters (and the seal's law) to the first recording and the others
// (explain_select.cc, judge_at_other_speeds).
#pragma once

#include <complex>
#include <functional>
#include <map>
#include <string>
#include <optional>
#include <vector>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/plant_model.h"
#include "explain_selector.h"

namespace ambdiag::detail {

class OtherSpeeds {
 public:
  // Throws InputError when a recording states no speed_rpm, or states the
  // primary's (then it is not another speed).
  OtherSpeeds(const std::vector<FrfData>& recordings, double primary_rpm);

  bool empty() const { return evals_.empty(); }

  // The weighted residuals (H_model - H_measured) / sigma of every other
  // recording, concatenated; `build(scale)` gives the variant with its
  // speed-law pieces multiplied by scale = (rpm / first rpm)^exponent. A
  // variant whose model fails at a speed gets a residual so large that
  // every fit steps away from it.
  std::vector<std::complex<double>> residual(const std::function<PlantVariant(double scale)>& build, double exponent);

  // How the improved model (with its speed laws in link tables) does at
  // each other speed, against the nominal.
  std::vector<SpeedCheck> report(const PlantModel& nominal, const PlantVariant& improved, double window_threshold);

 private:
  std::vector<PlantFrfEvaluator> evals_;
  double primary_rpm_;
};

// Writes a seal cross-coupling's speed law into its link's speed table, so
// the improved model holds at other speeds: `k`, `c` were added at
// `rpm0` (kxy = -kyx += k, cxy = -cyx += c); at speed r they become
// k (r / rpm0)^n. Rows at 0.5 .. 1.5 x rpm0 in steps of 1/8 and at every
// row the link had (the other coefficients kept exactly: a piecewise-linear
// table with points inserted is the same function); held beyond, as the
// plant format holds every table.
void write_speed_law(Link& l, double k, double c, double exponent, double rpm0);

// The selection with its speed-law pieces (a seal's cross-coupling)
// multiplied by `scale`, and whether it has any.
std::vector<Selected> scaled_law(std::vector<Selected> sel, double scale);
bool has_law(const std::vector<Selected>& sel);

struct SpeedJudgement {
  std::map<std::string, nlohmann::json> refuted;  // by claim id: what the other speeds ruled out in its place
  std::map<std::string, double> exponent;         // by claim id: a seal claim's fitted speed law
  std::optional<double> law;                      // of the whole selection
};

// Recordings at other speeds judge each claim against its alternatives: each,
// in the claim's place, has its parameters (and the seal's speed law)
// fitted jointly to the first recording's lines and the others; one whose
// fit is worse by more than 2 ln 100 is ruled out (a likelihood ratio of
// 100; fits, not penalised, as in Selector::alternatives). Where that is the
// claim, the best alternative takes its place. The winner keeps its joint
// fit: the improved model is fitted to every recording. `sel` and
// `alternatives` are updated in place.
SpeedJudgement judge_at_other_speeds(Selector& engine, OtherSpeeds& others, std::vector<Selected>& sel,
                                     std::vector<Selector::Alternative>& alternatives,
                                     const std::function<void(const std::string&)>& progress);

}  // namespace ambdiag::detail
