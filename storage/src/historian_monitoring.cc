// Historian: monitoring snapshots (table monitoring_snapshots, schema v2).
#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

// The 24 value columns after pump_id, time_ns, received_at, speed_rpm, in
// the order of values() below.
#define AMBDIAG_MONITORING_VALUES                                                                          \
  "force_1x_amp_n_ax, force_1x_amp_n_ay, force_1x_amp_n_bx, force_1x_amp_n_by, "                          \
  "force_1x_phase_rad_ax, force_1x_phase_rad_ay, force_1x_phase_rad_bx, force_1x_phase_rad_by, "          \
  "force_2x_amp_n_ax, force_2x_amp_n_ay, force_2x_amp_n_bx, force_2x_amp_n_by, "                          \
  "force_2x_phase_rad_ax, force_2x_phase_rad_ay, force_2x_phase_rad_bx, force_2x_phase_rad_by, "          \
  "orbit_major_m_a, orbit_major_m_b, orbit_minor_m_a, orbit_minor_m_b, "                                  \
  "orbit_center_x_m_a, orbit_center_x_m_b, orbit_center_y_m_a, orbit_center_y_m_b"
constexpr int kValues = 24;

template <class S>
auto values(S& s) {  // pointers to the 24 values, S = (const) MonitoringSnapshot
  std::array<decltype(&s.speed_rpm), kValues> v{};
  int i = 0;
  for (auto* a : {&s.force_1x_amp_n, &s.force_1x_phase_rad, &s.force_2x_amp_n, &s.force_2x_phase_rad})
    for (auto& x : *a) v[static_cast<size_t>(i++)] = &x;
  for (auto* a : {&s.orbit_major_m, &s.orbit_minor_m, &s.orbit_center_x_m, &s.orbit_center_y_m})
    for (auto& x : *a) v[static_cast<size_t>(i++)] = &x;
  return v;
}

}  // namespace

PutResult Historian::put_monitoring(std::span<const MonitoringSnapshot> snapshots) {
  impl_->require_writer("put_monitoring");
  for (const auto& s : snapshots) validate(s);
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  PutResult r;
  for (const auto& s : snapshots) {
    impl_->register_pump(s.pump_id, now);
    auto& ins = impl_->stmt(
        "INSERT INTO monitoring_snapshots (pump_id, time_ns, received_at, speed_rpm, " AMBDIAG_MONITORING_VALUES
        ") VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
        "ON CONFLICT (pump_id, time_ns) DO NOTHING");
    ins.bind(1, s.pump_id).bind(2, s.time_ns).bind(3, now).bind(4, s.speed_rpm);
    int col = 5;
    for (const double* v : values(s)) ins.bind(col++, *v);
    ins.run();
    if (impl_->db.changes() == 1)
      ++r.stored;
    else
      ++r.duplicates;
  }
  tx.commit();
  return r;
}

std::vector<MonitoringSnapshot> Historian::list_monitoring(const std::string& pump_id, std::int64_t since_ns,
                                                           std::int64_t limit) {
  if (limit < 1) throw InputError("list_monitoring: limit must be >= 1");
  auto& s = impl_->stmt("SELECT time_ns, speed_rpm, " AMBDIAG_MONITORING_VALUES
                        " FROM monitoring_snapshots WHERE pump_id = ? AND time_ns >= ? ORDER BY time_ns LIMIT ?");
  s.bind(1, pump_id).bind(2, since_ns).bind(3, limit);
  std::vector<MonitoringSnapshot> out;
  while (s.step()) {
    MonitoringSnapshot m;
    m.pump_id = pump_id;
    m.time_ns = s.col_int(0);
    m.speed_rpm = s.col_double(1);
    int col = 2;
    for (double* v : values(m)) *v = s.col_double(col++);
    out.push_back(std::move(m));
  }
  return out;
}

}  // namespace ambdiag::storage
