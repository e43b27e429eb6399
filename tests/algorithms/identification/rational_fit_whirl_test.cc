// Whirl pairs of a machine the fit has never seen (issue 18): the
// four-stage pump of four_stage_pump.h, its 5 x 5 FRF synthesized from the
// model with 1 % noise (sigma columns, seeded), fitted with automatic order
// and compared with the model's modal analysis at the speed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "ambdiag/algorithms/identification/mode_labels.h"
#include "ambdiag/algorithms/identification/rational_fit.h"
#include "ambdiag/algorithms/model/frf_synthesis.h"
#include "ambdiag/algorithms/model/modal_analysis.h"
#include "explain_support.h"
#include "four_stage_pump.h"

namespace ambdiag {
namespace {

// Truth: the lateral and axial modes below 1000 Hz with zeta < 0.2.
std::vector<Mode> truth_modes(const PlantModel& p) {
  ModalOptions mo;
  mo.f_max_hz = 1000.0;
  std::vector<Mode> out;
  for (const Mode& m : modal_analysis(p, p.speed_rpm, mo).modes)
    if (!m.overdamped && m.f_hz < 1000.0 && m.zeta < 0.2) out.push_back(m);
  return out;
}

const ModeDescription* nearest(const std::vector<ModeDescription>& found, double f_hz) {
  const ModeDescription* best = nullptr;
  for (const auto& d : found)
    if (!best || std::abs(d.mode.f_hz - f_hz) < std::abs(best->mode.f_hz - f_hz)) best = &d;
  return best;
}

// The first bending mode whirls backward at 268.1 Hz (zeta 0.103) and
// forward at 277.8 Hz (zeta 0.114), 3.6 % apart (their half-power bands
// overlap 6 x), 6 % below a housing mode at 296 Hz, and the sensors sit near
// its nodes (peak 35-45 sigma). In 16 noise realisations both whirl modes
// must be found within 0.5 % in frequency and 10 % (or 2 reported sd) in
// damping, with the right whirl, as two modes; and no truth mode may be
// missed: each has its own identified mode within 2 %. Before the joint
// refit of close pairs (rational_fit.cc, refit_close_pairs) the fit pushed
// the pair apart in realisations 5 and 13 (+0.53 %; -0.67 / +1.56 %): the
// free fit had merged it and the other poles, placed around the merged
// pair, made the modal refit fail its likelihood-ratio test.
TEST(RationalFitWhirl, ResolvesAHeavilyDampedWhirlPairOfAFourStagePump) {
  const PlantModel p = testing::four_stage_pump();
  const std::vector<Mode> truth = truth_modes(p);
  std::vector<const Mode*> pair;
  for (const Mode& m : truth)
    if (m.kind == "rotor" && m.f_hz > 250.0 && m.f_hz < 300.0) pair.push_back(&m);
  ASSERT_EQ(pair.size(), 2u);  // the machine is what the test says
  ASSERT_EQ(pair[0]->whirl, Whirl::backward);
  ASSERT_EQ(pair[1]->whirl, Whirl::forward);
  ASSERT_GT(pair[0]->zeta, 0.10);
  ASSERT_NEAR(pair[1]->f_hz / pair[0]->f_hz, 1.035, 0.01);

  for (unsigned seed = 1; seed <= 16; ++seed) {
    const FrfData f = testing::noisy_recording(PlantVariant{p}, frequency_grid(1.0, 1000.0, 1.0), seed);
    const RationalFitResult fit = fit_rational(f);
    std::vector<ModeDescription> found;
    for (const auto& m : fit.modes) found.push_back(describe_mode(m, fit, f, &p));
    std::vector<const ModeDescription*> used;
    for (const Mode& t : truth) {
      const ModeDescription* d = nearest(found, t.f_hz);
      ASSERT_NE(d, nullptr) << "seed " << seed;
      const IdentifiedMode& m = d->mode;
      const double ef = (m.f_hz - t.f_hz) / t.f_hz, ez = (m.zeta - t.zeta) / t.zeta;
      std::printf("seed %2u %-24s %-8s %7.2f Hz %.4f: f %+.3f %% zeta %+.1f %% (sd %.1f %%) %s\n", seed,
                  t.label.c_str(), to_string(t.whirl).c_str(), t.f_hz, t.zeta, 100 * ef, 100 * ez,
                  100 * m.zeta_sd / t.zeta, to_string(d->whirl).c_str());
      EXPECT_LT(std::abs(ef), 0.02) << "seed " << seed << ": " << t.label << " at " << t.f_hz << " Hz missed";
      EXPECT_EQ(std::count(used.begin(), used.end(), d), 0)
          << "seed " << seed << ": " << t.label << " merged at " << m.f_hz << " Hz";
      used.push_back(d);
      if (&t != pair[0] && &t != pair[1]) continue;
      EXPECT_LT(std::abs(ef), 0.005) << "seed " << seed << " " << to_string(t.whirl) << ": f " << m.f_hz
                                     << " vs " << t.f_hz;
      EXPECT_LT(std::abs(m.zeta - t.zeta), std::max(0.10 * t.zeta, 2.0 * m.zeta_sd))
          << "seed " << seed << " " << to_string(t.whirl) << ": zeta " << m.zeta << " vs " << t.zeta;
      EXPECT_EQ(d->whirl, t.whirl) << "seed " << seed << " at " << m.f_hz << " Hz";
    }
  }
}

}  // namespace
}  // namespace ambdiag
