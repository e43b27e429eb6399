// Monitoring snapshots: the condition summary an edge agent sends between
// identification runs (proto ambdiag_v1_MonitoringSnapshot), as the
// historian keeps it (table monitoring_snapshots, schema v2; docs/storage.md).
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace ambdiag::storage {

struct MonitoringSnapshot {
  std::string pump_id;
  std::int64_t time_ns = 0;  // agent clock, ns since the Unix epoch (UTC)
  double speed_rpm = 0.0;
  // Bearing force harmonics, index order Ax, Ay, Bx, By.
  std::array<double, 4> force_1x_amp_n{}, force_1x_phase_rad{}, force_2x_amp_n{}, force_2x_phase_rad{};
  // Orbit per bearing (A, B): peak semi-axes and centre.
  std::array<double, 2> orbit_major_m{}, orbit_minor_m{}, orbit_center_x_m{}, orbit_center_y_m{};
};

// Throws InputError naming the first bad field: empty or over-long pump_id
// (1..128 bytes), time before 2000-01-01 or after 2200-01-01, a value that is
// not finite, a negative speed, amplitude or semi-axis, a minor semi-axis
// larger than the major one, a phase outside [-2 pi, 2 pi] (both the
// (-pi, pi] and [0, 2 pi) conventions pass).
void validate(const MonitoringSnapshot& s);

// "2026-11-22T10:00:00.123456789Z" (nanoseconds kept; trailing zeros of the
// fraction dropped, no fraction for whole seconds).
std::string utc_from_ns(std::int64_t ns_since_epoch);
// Parses "YYYY-MM-DDThh:mm:ss[.fraction](Z|+hh:mm|-hh:mm)" or a plain integer
// of nanoseconds since the epoch. Throws InputError naming `what` otherwise.
std::int64_t ns_from_utc(const std::string& text, const std::string& what);

}  // namespace ambdiag::storage
