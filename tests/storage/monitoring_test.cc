// Monitoring snapshots: validation, storage and query in the historian, and
// the UTC time helpers used to page through them.
#include "ambdiag/storage/monitoring.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

constexpr std::int64_t kT0 = 1'795'000'000'000'000'000;  // 2026-11-18T11:06:40Z

MonitoringSnapshot snapshot(const std::string& pump, std::int64_t t_ns, double scale) {
  MonitoringSnapshot s;
  s.pump_id = pump;
  s.time_ns = t_ns;
  s.speed_rpm = 2950 * scale;
  for (size_t i = 0; i < 4; ++i) {
    s.force_1x_amp_n[i] = 10.0 * scale + static_cast<double>(i);
    s.force_1x_phase_rad[i] = -3.0 + static_cast<double>(i);
    s.force_2x_amp_n[i] = 1.0 * scale + 0.1 * static_cast<double>(i);
    s.force_2x_phase_rad[i] = 0.5 * static_cast<double>(i);
  }
  for (size_t b = 0; b < 2; ++b) {
    s.orbit_major_m[b] = 20e-6 * scale;
    s.orbit_minor_m[b] = 5e-6 * scale;
    s.orbit_center_x_m[b] = -1e-6 * static_cast<double>(b + 1);
    s.orbit_center_y_m[b] = 2e-6;
  }
  return s;
}

bool same(const MonitoringSnapshot& a, const MonitoringSnapshot& b) {
  return a.pump_id == b.pump_id && a.time_ns == b.time_ns && a.speed_rpm == b.speed_rpm &&
         a.force_1x_amp_n == b.force_1x_amp_n && a.force_1x_phase_rad == b.force_1x_phase_rad &&
         a.force_2x_amp_n == b.force_2x_amp_n && a.force_2x_phase_rad == b.force_2x_phase_rad &&
         a.orbit_major_m == b.orbit_major_m && a.orbit_minor_m == b.orbit_minor_m &&
         a.orbit_center_x_m == b.orbit_center_x_m && a.orbit_center_y_m == b.orbit_center_y_m;
}

class MonitoringTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(MonitoringTest);

TEST_P(MonitoringTest, SnapshotsRoundTripInTimeOrderAndRepeatsAreDuplicates) {
  auto h = Historian::open(location());
  std::vector<MonitoringSnapshot> in;
  for (int k = 4; k >= 0; --k) in.push_back(snapshot("P-9", kT0 + k * 1'000'000'000LL, 1.0 + 0.1 * k));
  const auto r = h.put_monitoring(in);
  EXPECT_EQ(r.stored, 5);
  EXPECT_EQ(h.put_monitoring(std::span(in).subspan(0, 2)).duplicates, 2);
  EXPECT_TRUE(h.find_pump("P-9"));  // registered by its first snapshot

  const auto all = h.list_monitoring("P-9", 0, 100);
  ASSERT_EQ(all.size(), 5u);
  for (size_t i = 0; i < all.size(); ++i) EXPECT_TRUE(same(all[i], in[4 - i])) << i;  // oldest first, bit-equal
  const auto page = h.list_monitoring("P-9", kT0 + 2'000'000'000LL, 2);  // since is inclusive
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].time_ns, kT0 + 2'000'000'000LL);
  EXPECT_EQ(page[1].time_ns, kT0 + 3'000'000'000LL);
  EXPECT_TRUE(h.list_monitoring("P-other", 0, 10).empty());
  EXPECT_THROW(h.list_monitoring("P-9", 0, 0), InputError);
}

TEST_P(MonitoringTest, InvalidSnapshotsAreRefusedNamingTheFieldAndNothingIsStored) {
  auto h = Historian::open(location());
  const auto good = snapshot("P-9", kT0, 1.0);
  EXPECT_NO_THROW(validate(good));
  struct Case {
    const char* field;
    void (*spoil)(MonitoringSnapshot&);
  };
  const Case cases[] = {
      {"pump_id", [](MonitoringSnapshot& s) { s.pump_id.clear(); }},
      {"pump_id", [](MonitoringSnapshot& s) { s.pump_id.assign(129, 'x'); }},
      {"time_ns", [](MonitoringSnapshot& s) { s.time_ns = 0; }},
      {"time_ns", [](MonitoringSnapshot& s) { s.time_ns = std::numeric_limits<std::int64_t>::max(); }},
      {"speed_rpm", [](MonitoringSnapshot& s) { s.speed_rpm = -1; }},
      {"force_1x_amp_n[2]", [](MonitoringSnapshot& s) { s.force_1x_amp_n[2] = std::nan(""); }},
      {"force_2x_amp_n[0]", [](MonitoringSnapshot& s) { s.force_2x_amp_n[0] = -0.5; }},
      {"force_1x_phase_rad[3]", [](MonitoringSnapshot& s) { s.force_1x_phase_rad[3] = 7.0; }},
      {"force_2x_phase_rad[1]", [](MonitoringSnapshot& s) { s.force_2x_phase_rad[1] = HUGE_VAL; }},
      {"orbit_major_m[1]", [](MonitoringSnapshot& s) { s.orbit_major_m[1] = -1e-6; }},
      {"orbit_minor_m[0]", [](MonitoringSnapshot& s) { s.orbit_minor_m[0] = 1.0; }},  // larger than major
      {"orbit_center_y_m[0]", [](MonitoringSnapshot& s) { s.orbit_center_y_m[0] = -HUGE_VAL; }},
  };
  for (const auto& c : cases) {
    MonitoringSnapshot s = good;
    c.spoil(s);
    try {
      validate(s);
      ADD_FAILURE() << c.field << " not refused";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << c.field << ": " << e.what();
    }
    const std::vector<MonitoringSnapshot> batch = {snapshot("P-9", kT0 + 1, 1.0), s};
    EXPECT_THROW(h.put_monitoring(batch), InputError) << c.field;
  }
  EXPECT_TRUE(h.list_monitoring("P-9", 0, 100).empty());  // not even the good one of each batch
  // Phases in [0, 2 pi) are as valid as in (-pi, pi].
  auto wrapped = good;
  wrapped.force_1x_phase_rad = {0.0, 3.5, 6.2, 1.0};
  EXPECT_NO_THROW(validate(wrapped));
}

TEST(UtcTime, FormatsAndParsesNanosecondTimes) {
  EXPECT_EQ(utc_from_ns(0), "1970-01-01T00:00:00Z");
  EXPECT_EQ(utc_from_ns(951'782'400'000'000'000LL), "2000-02-29T00:00:00Z");  // a leap day
  EXPECT_EQ(utc_from_ns(1'795'003'200'500'000'000LL), "2026-11-18T12:00:00.5Z");
  EXPECT_EQ(utc_from_ns(-1), "1969-12-31T23:59:59.999999999Z");
  for (std::int64_t t : std::vector<std::int64_t>{0, -1, kT0, kT0 + 123'456'789, 4'102'444'800'000'000'001})
    EXPECT_EQ(ns_from_utc(utc_from_ns(t), "t"), t) << t;
  EXPECT_EQ(ns_from_utc("2026-11-18T14:00:00.5+02:00", "t"), 1'795'003'200'500'000'000LL);
  EXPECT_EQ(ns_from_utc("2026-11-18T12:00:00.500000000123z", "t"), 1'795'003'200'500'000'000LL);  // beyond ns: cut
  EXPECT_EQ(ns_from_utc("1795003200500000000", "t"), 1'795'003'200'500'000'000LL);
  for (const char* bad : {"", "2026-11-18", "2026-11-18T10:40:00", "2026-13-01T00:00:00Z", "2026-02-30T00:00:00Z",
                          "2026-11-18T24:00:00Z", "2026-11-18T10:40:00.Z", "2026-11-18T10:40:00Zjunk", "abc",
                          "9999999999999999999", "2026-11-18T10:40:00+2:00", "9999-01-01T00:00:00Z"}) {
    try {
      ns_from_utc(bad, "since");
      ADD_FAILURE() << "'" << bad << "' accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("since"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace ambdiag::storage
