#include "ambdiag/algorithms/model/campbell.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/plant_model.h"
#include "test_support.h"
#include "xml_check.h"

namespace ambdiag {
namespace {

using nlohmann::json;

// Friswell et al. example 5.9.1 (two disks, isotropic undamped bearings).
PlantModel friswell_5_9_1() {
  std::ifstream in(testing::shared_data() / "../reference/peer-rotor-cases.json");
  const json peers = json::parse(in);
  for (const auto& c : peers["cases"]) {
    if (c["id"] == "friswell_5_9_1") return plant_from_json(c["plant"]);
  }
  throw std::runtime_error("friswell_5_9_1 not in peer-rotor-cases.json");
}

const CampbellTrack* find_track(const CampbellResult& r, const std::string& label) {
  for (const auto& t : r.tracks)
    if (t.label == label) return &t;
  return nullptr;
}

// Root of g on [a, b] (g(a), g(b) of opposite sign) by bisection.
double bisect(const std::function<double(double)>& g, double a, double b, double tol) {
  double ga = g(a);
  while (b - a > tol) {
    const double m = 0.5 * (a + b), gm = g(m);
    if ((gm < 0) == (ga < 0)) {
      a = m;
      ga = gm;
    } else {
      b = m;
    }
  }
  return 0.5 * (a + b);
}

// The mode of modal_analysis at `rpm` with this whirl nearest to f_hz.
Mode nearest_mode(const PlantModel& p, double rpm, Whirl whirl, double f_hz) {
  ModalOptions o;
  o.overdamped = false;
  const ModalResult r = modal_analysis(p, rpm, o);
  const Mode* best = nullptr;
  for (const auto& m : r.modes) {
    if (m.kind != "rotor" || m.whirl != whirl) continue;
    if (!best || std::abs(m.f_hz - f_hz) < std::abs(best->f_hz - f_hz)) best = &m;
  }
  if (!best) throw std::runtime_error("no mode");
  return *best;
}

// Up to 30000 rpm the third forward mode (114 Hz at standstill) rises through
// the fourth backward one (170 Hz falling), and 3B falls through 2F. A
// tracker that sorts by frequency would swap them; MAC tracking must not.
TEST(Campbell, FollowsForwardModeRisingThroughBackwardMode) {
  CampbellOptions o;
  o.speed_max_rpm = 30000;
  o.n_speeds = 61;
  o.f_max_hz = 200;
  const CampbellResult r = campbell(friswell_5_9_1(), o);
  ASSERT_EQ(r.speeds_rpm.size(), 61u);
  EXPECT_GT(r.worst_mac, 0.95);
  const CampbellTrack* f3 = find_track(r, "3F");
  const CampbellTrack* b4 = find_track(r, "4B");
  const CampbellTrack* b3 = find_track(r, "3B");
  const CampbellTrack* f2 = find_track(r, "2F");
  ASSERT_TRUE(f3 && b4 && b3 && f2);
  EXPECT_NEAR(f3->f_hz.front(), 114.08, 0.01);
  EXPECT_NEAR(b4->f_hz.front(), 169.68, 0.01);
  // They do cross.
  EXPECT_LT(f3->f_hz.front(), b4->f_hz.front());
  EXPECT_GT(f3->f_hz.back(), b4->f_hz.back());
  EXPECT_GT(b3->f_hz.front(), f2->f_hz.front() - 1e-3);
  EXPECT_LT(b3->f_hz.back(), f2->f_hz.back());
  // Every track keeps its whirl (from modal_analysis' shape, which the tracker
  // does not use) and moves monotonically: forward up, backward down.
  for (const auto& t : r.tracks) {
    ASSERT_NE(t.whirl, Whirl::none) << t.label;
    for (size_t i = 1; i < r.speeds_rpm.size(); ++i) {
      if (std::isnan(t.f_hz[i]) || std::isnan(t.f_hz[i - 1])) continue;
      EXPECT_EQ(t.whirl_at[i], t.whirl) << t.label << " at " << r.speeds_rpm[i] << " rpm";
      const double rise_hz = t.f_hz[i] - t.f_hz[i - 1];
      EXPECT_GE(t.whirl == Whirl::forward ? rise_hz : -rise_hz, 0.0) << t.label;
      EXPECT_GT(t.mac[i], 0.95) << t.label;
    }
  }
  // Undamped: neutrally stable, no spurious onset from round-off.
  EXPECT_TRUE(r.stable);
  EXPECT_FALSE(r.instability_onset_rpm);
}

// Critical speeds (linear interpolation between 500 rpm steps) against the
// crossing of the same mode with 1x found by bisection on modal_analysis.
TEST(Campbell, CriticalSpeedsAgreeWithBisectionOnModalAnalysis) {
  const PlantModel plant = friswell_5_9_1();
  CampbellOptions o;
  o.speed_max_rpm = 12000;
  o.n_speeds = 25;
  o.f_max_hz = 250;
  const CampbellResult r = campbell(plant, o);
  // 1B, 1F, 2B, 2F, 3B, 3F, 4B, 4F all cross below 12000 rpm.
  ASSERT_EQ(r.critical_speeds.size(), 8u);
  const double step_rpm = r.speeds_rpm[1] - r.speeds_rpm[0];
  double worst_rel = 0.0;
  for (const auto& c : r.critical_speeds) {
    EXPECT_DOUBLE_EQ(c.f_hz, c.speed_rpm / 60.0);
    EXPECT_EQ(c.whirl, r.tracks[static_cast<size_t>(c.track)].whirl);
    EXPECT_NEAR(c.log_dec, 0.0, 1e-5);
    const double a = std::floor(c.speed_rpm / step_rpm) * step_rpm, b = a + step_rpm;
    const auto& t = r.tracks[static_cast<size_t>(c.track)];
    auto g = [&](double rpm) {
      // The track's mode: same whirl, nearest to the track's (linear) frequency.
      const double u = (rpm - a) / step_rpm;
      const size_t i = static_cast<size_t>(std::lround(a / step_rpm));
      const double f_guess = t.f_hz[i] + u * (t.f_hz[i + 1] - t.f_hz[i]);
      return nearest_mode(plant, rpm, c.whirl, f_guess).f_hz - rpm / 60.0;
    };
    const double exact = bisect(g, a, b, 0.01);
    const double rel = std::abs(c.speed_rpm - exact) / exact;
    worst_rel = std::max(worst_rel, rel);
    EXPECT_LT(rel, 5e-4) << c.label << " campbell " << c.speed_rpm << " rpm, bisection " << exact << " rpm";
  }
  RecordProperty("worst_relative_error", std::to_string(worst_rel));
}

// A destabilising cross-coupled stiffness that grows with speed: the first
// forward mode loses its damping and the onset matches modal_analysis.
TEST(Campbell, FindsOnsetOfInstability) {
  PlantModel plant = friswell_5_9_1();
  for (auto& l : plant.links) {
    l.coef[static_cast<int>(LinkCoef::cxx)] = 2000;
    l.coef[static_cast<int>(LinkCoef::cyy)] = 2000;
  }
  Link seal;
  seal.name = "seal";
  seal.kind = "seal";
  seal.node = 3;
  LinkTableRow lo, hi;
  lo.rpm = 0;
  lo.values[static_cast<int>(LinkCoef::kxy)] = 0.0;
  lo.values[static_cast<int>(LinkCoef::kyx)] = 0.0;
  hi.rpm = 10000;
  hi.values[static_cast<int>(LinkCoef::kxy)] = 1e5;
  hi.values[static_cast<int>(LinkCoef::kyx)] = -1e5;
  seal.table = {lo, hi};
  plant.links.push_back(seal);
  CampbellOptions o;
  o.speed_max_rpm = 10000;
  o.n_speeds = 21;
  o.f_max_hz = 200;
  const CampbellResult r = campbell(plant, o);
  EXPECT_FALSE(r.stable);
  ASSERT_TRUE(r.instability_onset_rpm);
  const CampbellTrack* f1 = find_track(r, "1F");
  const CampbellTrack* b1 = find_track(r, "1B");
  ASSERT_TRUE(f1 && b1);
  EXPECT_EQ(f1->instability_onset_rpm, r.instability_onset_rpm);
  EXPECT_FALSE(b1->instability_onset_rpm);
  EXPECT_GT(b1->log_dec.back(), b1->log_dec.front());  // kxy > 0 damps backward whirl
  EXPECT_LT(f1->min_log_dec, 0.0);
  EXPECT_EQ(f1->min_log_dec_speed_rpm, 10000.0);
  const double onset = *r.instability_onset_rpm;
  const double a = std::floor(onset / 500.0) * 500.0;
  const double exact =
      bisect([&](double rpm) { return nearest_mode(plant, rpm, Whirl::forward, f1->f_hz[0]).zeta; }, a,
             a + 500.0, 0.1);
  EXPECT_NEAR(onset, exact, 1e-3 * exact);
  RecordProperty("onset_rpm", std::to_string(onset));
  RecordProperty("onset_bisection_rpm", std::to_string(exact));
}

TEST(Campbell, WritesWellFormedSvgAndJson) {
  CampbellOptions o;
  o.speed_max_rpm = 12000;
  o.n_speeds = 13;
  o.f_max_hz = 200;
  PlantModel plant = friswell_5_9_1();
  plant.housings.push_back(Housing{"housing <A> & co", "A", {"x", "y"}, 150.0, 0.05, 40.0});
  const CampbellResult r = campbell(plant, o);
  ASSERT_EQ(r.fixed_modes.size(), 1u);
  EXPECT_EQ(r.fixed_modes[0].kind, "housing");
  const std::string svg = campbell_svg(r);
  EXPECT_EQ(testing::xml_problem(svg), "");
  for (const char* s :
       {">1F<", ">1B<", ">1x<", ">critical speeds<", ">speed (rpm)<", "housing &lt;A&gt; &amp; co"}) {
    EXPECT_NE(svg.find(s), std::string::npos) << s;
  }
  const json j = campbell_to_json(r);
  EXPECT_EQ(j["speeds_rpm"].size(), 13u);
  EXPECT_EQ(j["tracks"].size(), r.tracks.size());
  EXPECT_EQ(j["tracks"][0]["f_hz"].size(), 13u);
  EXPECT_EQ(j["critical_speeds"].size(), r.critical_speeds.size());
  EXPECT_TRUE(j["instability_onset_rpm"].is_null());
  EXPECT_EQ(j["tracks"][0]["mac"][0], nullptr);  // no previous speed
  // JSON text is valid (no NaN literals).
  EXPECT_NO_THROW(json::parse(j.dump()));
}

TEST(Campbell, RefusesInvalidOptions) {
  const PlantModel plant = friswell_5_9_1();
  auto run = [&](auto edit) {
    CampbellOptions o;
    edit(o);
    return campbell(plant, o);
  };
  EXPECT_THROW(run([](CampbellOptions& o) { o.n_speeds = 0; }), InputError);
  EXPECT_THROW(run([](CampbellOptions& o) { o.f_max_hz = -1; }), InputError);
  EXPECT_THROW(run([](CampbellOptions& o) { o.speed_max_rpm = -5; }), InputError);
  EXPECT_THROW(run([](CampbellOptions& o) { o.speed_min_rpm = std::nan(""); }), InputError);
  // One speed is a valid (if dull) diagram.
  const CampbellResult one = run([](CampbellOptions& o) {
    o.speed_min_rpm = o.speed_max_rpm = 3000;
    o.n_speeds = 1;
  });
  EXPECT_EQ(one.speeds_rpm.size(), 1u);
  EXPECT_FALSE(one.tracks.empty());
  EXPECT_EQ(testing::xml_problem(campbell_svg(one)), "");
}

}  // namespace
}  // namespace ambdiag
