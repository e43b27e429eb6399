// Prognosis against lines with known crossing times: the estimate, the
// interval's coverage over many seeded draws (equal and unequal sd), and
// the refusals (too few points, too short, flat, away from the limit).
#include "trends/prognosis.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {
namespace {

constexpr double kDay = 86400.0;

// y = 1 + 0.01 / day * t, 30 daily points: reaches 2 at day 100.
std::vector<PrognosisPoint> draw(std::mt19937& rng, bool unequal_sd, bool give_sd = true) {
  std::vector<PrognosisPoint> out;
  for (int i = 0; i < 30; ++i) {
    const double sd = unequal_sd ? (i % 3 == 0 ? 0.01 : 0.06) : 0.03;
    const double t = 1.7e9 + i * kDay;
    out.push_back({t, 1.0 + 0.01 * i + std::normal_distribution<double>(0.0, sd)(rng),
                   give_sd ? std::optional<double>(sd) : std::nullopt});
  }
  return out;
}

const double kTrueCrossing = 1.7e9 + 100 * kDay;

TEST(Prognosis, ExactPointsGiveTheCrossingOfTheLine) {
  std::vector<PrognosisPoint> pts;
  for (int i = 0; i < 10; ++i) pts.push_back({1.7e9 + i * kDay, 1.0 + 0.01 * i + (i % 2 ? 1e-4 : -1e-4), std::nullopt});
  std::ranges::reverse(pts);  // order does not matter
  const auto p = prognose(pts, 2.0);
  ASSERT_EQ(p.status, PrognosisStatus::ok) << p.reason;
  EXPECT_NEAR(*p.crossing_s, kTrueCrossing, 0.1 * kDay);  // the +-1e-4 zigzag tilts the line a little
  EXPECT_LT(*p.lower_s, *p.crossing_s);
  EXPECT_GT(*p.upper_s, *p.crossing_s);
  EXPECT_NEAR(p.slope_per_s * kDay, 0.01, 1e-4);
  EXPECT_FALSE(p.weighted);
}

// The 90 % interval covers the true crossing in 90 % of the draws, with
// weights from the sd (unequal scatter) and without them.
void expect_coverage(bool unequal_sd, bool give_sd) {
  std::mt19937 rng(unequal_sd ? 11 : 7);
  const int draws = 3000;
  int covered = 0, ok = 0;
  std::vector<double> estimates;
  for (int k = 0; k < draws; ++k) {
    const auto p = prognose(draw(rng, unequal_sd, give_sd), 2.0);
    if (p.status != PrognosisStatus::ok) continue;
    ++ok;
    EXPECT_EQ(p.weighted, give_sd);
    covered += *p.lower_s <= kTrueCrossing && kTrueCrossing <= *p.upper_s;
    estimates.push_back(*p.crossing_s);
  }
  EXPECT_GE(ok, draws * 99 / 100);  // the slope is 10 sd and more: a date nearly always
  const double coverage = static_cast<double>(covered) / ok;
  // Binomial sd of the share at 3000 draws: 0.0055; 3.5 sd either side.
  EXPECT_NEAR(coverage, 0.90, 0.02) << "unequal_sd " << unequal_sd << " give_sd " << give_sd;
  std::ranges::sort(estimates);
  EXPECT_NEAR(estimates[estimates.size() / 2], kTrueCrossing, 3 * kDay);  // median unbiased enough
}

TEST(Prognosis, IntervalCoversTheTrueCrossingAtItsLevel) { expect_coverage(false, true); }
TEST(Prognosis, WeightsFromTheSdKeepTheCoverageWithUnequalScatter) { expect_coverage(true, true); }
TEST(Prognosis, WithoutSdTheFitIsUnweighted) { expect_coverage(false, false); }

TEST(Prognosis, WeightingByTheSdNarrowsTheInterval) {
  std::mt19937 rng(3);
  double weighted = 0, plain = 0;
  for (int k = 0; k < 200; ++k) {
    auto pts = draw(rng, true);
    const auto w = prognose(pts, 2.0);
    for (auto& x : pts) x.sd.reset();
    const auto u = prognose(pts, 2.0);
    if (w.status != PrognosisStatus::ok || u.status != PrognosisStatus::ok) continue;
    weighted += *w.upper_s - *w.lower_s;
    plain += *u.upper_s - *u.lower_s;
  }
  EXPECT_LT(weighted, 0.9 * plain);
}

TEST(Prognosis, SaysWhyItGivesNoDate) {
  std::mt19937 rng(1);
  auto pts = draw(rng, false);
  EXPECT_EQ(prognose({pts.begin(), pts.begin() + 4}, 2.0).status, PrognosisStatus::not_enough_points);
  EXPECT_EQ(prognose({}, 2.0).status, PrognosisStatus::not_enough_points);
  std::vector<PrognosisPoint> quick;
  for (int i = 0; i < 10; ++i) quick.push_back({1.7e9 + i * 60.0, 1.0 + 0.1 * i, std::nullopt});  // 9 minutes
  const auto q = prognose(quick, 2.0);
  EXPECT_EQ(q.status, PrognosisStatus::not_enough_points);
  EXPECT_NE(q.reason.find("540 s"), std::string::npos) << q.reason;
  // Away from the limit: the same line against a limit below it.
  EXPECT_EQ(prognose(pts, 0.5).status, PrognosisStatus::not_trending);
  // Flat within its scatter.
  for (auto& x : pts) x.value = 1.0 + std::normal_distribution<double>(0.0, 0.03)(rng);
  const auto flat = prognose(pts, 2.0);
  EXPECT_EQ(flat.status, PrognosisStatus::not_trending);
  EXPECT_FALSE(flat.crossing_s);
  EXPECT_THROW(prognose(pts, std::nan("")), InputError);
}

TEST(Prognosis, ALineAlreadyBeyondTheLimitHasReachedIt) {
  std::mt19937 rng(2);
  const auto p = prognose(draw(rng, false), 1.2);  // crossed at day 20 of 29
  ASSERT_EQ(p.status, PrognosisStatus::limit_reached) << p.reason;
  EXPECT_NEAR(*p.crossing_s, 1.7e9 + 20 * kDay, 3 * kDay);
  // A falling series towards a lower limit.
  std::vector<PrognosisPoint> down;
  for (int i = 0; i < 20; ++i) down.push_back({i * kDay, 5.0 - 0.1 * i + (i % 2 ? 0.01 : -0.01), 0.01});
  const auto d = prognose(down, 2.0);
  ASSERT_EQ(d.status, PrognosisStatus::ok);
  EXPECT_NEAR(*d.crossing_s, 30 * kDay, 0.5 * kDay);
}

TEST(Prognosis, WearClearanceFactorsHaveADefaultLimit) {
  EXPECT_EQ(default_prognosis_limit("fault.balance_piston_wear.clearance_factor"), 2.0);
  EXPECT_EQ(default_prognosis_limit("fault.impeller_seal_wear.clearance_factor"), 2.0);
  EXPECT_FALSE(default_prognosis_limit("detection.ratio"));
}

}  // namespace
}  // namespace ambdiag::server::detail
