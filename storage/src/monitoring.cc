#include "ambdiag/storage/monitoring.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <span>

#include "ambdiag/core/error.h"

namespace ambdiag::storage {

namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;
constexpr std::int64_t kMinTimeNs = 946'684'800 * kNsPerS;        // 2000-01-01T00:00:00Z
constexpr std::int64_t kMaxTimeNs = 7'258'118'400LL * kNsPerS;     // 2200-01-01T00:00:00Z

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's
// days_from_civil), and back.
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

void civil_from_days(std::int64_t z, std::int64_t& y, unsigned& m, unsigned& d) {
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const auto doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  d = doy - (153 * mp + 2) / 5 + 1;
  m = mp < 10 ? mp + 3 : mp - 9;
  y = static_cast<std::int64_t>(yoe) + era * 400 + (m <= 2);
}

void check_values(std::span<const double> v, const char* name, double lo, double hi) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i]) || v[i] < lo || v[i] > hi) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "monitoring snapshot: %s[%zu] = %g is %s", name, i, v[i],
                    std::isfinite(v[i]) ? "out of range" : "not finite");
      throw InputError(buf);
    }
  }
}

}  // namespace

void validate(const MonitoringSnapshot& s) {
  if (s.pump_id.empty() || s.pump_id.size() > 128)
    throw InputError("monitoring snapshot: pump_id must have 1..128 bytes, has " + std::to_string(s.pump_id.size()));
  if (s.time_ns < kMinTimeNs || s.time_ns > kMaxTimeNs)
    throw InputError("monitoring snapshot of pump '" + s.pump_id + "': time_ns " + std::to_string(s.time_ns) +
                     " is not between 2000-01-01 and 2200-01-01");
  constexpr double kInf = HUGE_VAL, kTwoPi = 2 * std::numbers::pi;
  check_values(std::span(&s.speed_rpm, 1), "speed_rpm", 0, kInf);
  check_values(s.force_1x_amp_n, "force_1x_amp_n", 0, kInf);
  check_values(s.force_2x_amp_n, "force_2x_amp_n", 0, kInf);
  check_values(s.force_1x_phase_rad, "force_1x_phase_rad", -kTwoPi, kTwoPi);
  check_values(s.force_2x_phase_rad, "force_2x_phase_rad", -kTwoPi, kTwoPi);
  check_values(s.orbit_major_m, "orbit_major_m", 0, kInf);
  check_values(s.orbit_minor_m, "orbit_minor_m", 0, kInf);
  check_values(s.orbit_center_x_m, "orbit_center_x_m", -kInf, kInf);
  check_values(s.orbit_center_y_m, "orbit_center_y_m", -kInf, kInf);
  for (size_t b = 0; b < 2; ++b)
    if (s.orbit_minor_m[b] > s.orbit_major_m[b])
      throw InputError("monitoring snapshot of pump '" + s.pump_id + "': orbit_minor_m[" + std::to_string(b) +
                       "] is larger than orbit_major_m[" + std::to_string(b) + "]");
}

std::string utc_from_ns(std::int64_t ns) {
  std::int64_t secs = ns / kNsPerS, frac = ns % kNsPerS;
  if (frac < 0) frac += kNsPerS, --secs;
  std::int64_t days = secs / 86400, sod = secs % 86400;
  if (sod < 0) sod += 86400, --days;
  std::int64_t y;
  unsigned m, d;
  civil_from_days(days, y, m, d);
  char buf[64];
  int n = std::snprintf(buf, sizeof buf, "%04lld-%02u-%02uT%02d:%02d:%02d", static_cast<long long>(y), m, d,
                        static_cast<int>(sod / 3600), static_cast<int>(sod / 60 % 60), static_cast<int>(sod % 60));
  if (frac != 0) {
    char f[16];
    std::snprintf(f, sizeof f, ".%09lld", static_cast<long long>(frac));
    std::string fs = f;
    while (fs.back() == '0') fs.pop_back();
    n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%s", fs.c_str());
  }
  std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "Z");
  return buf;
}

std::int64_t ns_from_utc(const std::string& t, const std::string& what) {
  const auto bad = [&]() -> InputError {
    return InputError(what + ": '" + t +
                      "' is neither a UTC time like 2026-11-22T10:00:00Z nor nanoseconds since the epoch");
  };
  if (!t.empty() && t.find_first_not_of("0123456789") == std::string::npos) {
    if (t.size() > 19 || (t.size() == 19 && t > "9223372036854775807")) throw bad();  // beyond int64
    return std::stoll(t);
  }
  const auto digits = [&](size_t at, size_t n) {
    if (at + n > t.size()) throw bad();
    std::int64_t v = 0;
    for (size_t i = at; i < at + n; ++i) {
      if (t[i] < '0' || t[i] > '9') throw bad();
      v = v * 10 + (t[i] - '0');
    }
    return v;
  };
  const auto expect = [&](size_t at, char c) {
    if (at >= t.size() || t[at] != c) throw bad();
  };
  const std::int64_t y = digits(0, 4);
  expect(4, '-');
  const std::int64_t mo = digits(5, 2);
  expect(7, '-');
  const std::int64_t d = digits(8, 2);
  if (t.size() <= 10 || (t[10] != 'T' && t[10] != 't' && t[10] != ' ')) throw bad();
  const std::int64_t h = digits(11, 2);
  expect(13, ':');
  const std::int64_t mi = digits(14, 2);
  expect(16, ':');
  const std::int64_t s = digits(17, 2);
  static constexpr int kDays[] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  if (mo < 1 || mo > 12 || d < 1 || d > kDays[mo - 1] || h > 23 || mi > 59 || s > 60) throw bad();
  size_t at = 19;
  std::int64_t frac = 0;
  if (at < t.size() && t[at] == '.') {
    size_t n = 0;
    for (++at; at < t.size() && t[at] >= '0' && t[at] <= '9'; ++at, ++n)
      if (n < 9) frac = frac * 10 + (t[at] - '0');
    if (n == 0) throw bad();
    for (; n < 9; ++n) frac *= 10;
  }
  std::int64_t offset_s = 0;
  if (at < t.size() && (t[at] == 'Z' || t[at] == 'z')) {
    ++at;
  } else if (at < t.size() && (t[at] == '+' || t[at] == '-')) {
    const std::int64_t oh = digits(at + 1, 2);
    expect(at + 3, ':');
    const std::int64_t om = digits(at + 4, 2);
    if (oh > 23 || om > 59) throw bad();
    offset_s = (t[at] == '+' ? 1 : -1) * (oh * 3600 + om * 60);
    at += 6;
  } else {
    throw bad();  // a time without zone is ambiguous
  }
  if (at != t.size()) throw bad();
  const std::int64_t secs =
      days_from_civil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d)) * 86400 + h * 3600 + mi * 60 + s - offset_s;
  if (secs < -9'000'000'000LL || secs > 9'000'000'000LL) throw bad();  // int64 ns span 1677..2262
  return secs * kNsPerS + frac;
}

}  // namespace ambdiag::storage
