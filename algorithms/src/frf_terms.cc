#include "frf_terms.h"

namespace ambdiag::detail {

namespace {

std::complex<double> sdof_compliance(double m_kg, double k_n_per_m, double c_ns_per_m, double w) {
  return 1.0 / std::complex<double>(k_n_per_m - w * w * m_kg, w * c_ns_per_m);
}

}  // namespace

LateralMaps lateral_maps(const PlantModel& plant, const RotorSystem& sys) {
  LateralMaps maps;
  std::vector<Eigen::RowVectorXd> rows;
  for (size_t i = 0; i < plant.sensors.size(); ++i) {
    const auto& s = plant.sensors[i];
    if (s.is_axial()) continue;
    maps.sensor_index.push_back(static_cast<int>(i));
    rows.push_back(sys.dof_row(lateral_dof(*s.node, s.dir)));
  }
  std::vector<Eigen::RowVectorXd> cols;
  for (size_t i = 0; i < plant.actuators.size(); ++i) {
    const auto& a = plant.actuators[i];
    if (a.is_axial()) continue;
    maps.actuator_index.push_back(static_cast<int>(i));
    cols.push_back(sys.dof_row(lateral_dof(*a.node, a.dir)));
  }
  maps.c_out.resize(static_cast<Eigen::Index>(rows.size()), sys.size());
  for (size_t r = 0; r < rows.size(); ++r) maps.c_out.row(static_cast<Eigen::Index>(r)) = rows[r];
  maps.b_in.resize(sys.size(), static_cast<Eigen::Index>(cols.size()));
  for (size_t c = 0; c < cols.size(); ++c) maps.b_in.col(static_cast<Eigen::Index>(c)) = cols[c].transpose();
  return maps;
}

std::complex<double> parallel_compliance(const PlantModel& plant, const MeasurementPoint& s, const MeasurementPoint& a,
                                         double w) {
  std::complex<double> h = 0.0;
  if (s.is_axial() != a.is_axial()) return h;
  if (s.is_axial()) {
    const AxialModel& ax = *plant.axial;
    h += sdof_compliance(ax.m_kg.value_or(plant.rotor_mass_kg()), ax.k_n_per_m, ax.c_ns_per_m, w);
    for (const auto& hs : ax.housings) {
      const double w0 = 2.0 * M_PI * hs.f_hz;
      h += sdof_compliance(hs.m_kg, hs.m_kg * w0 * w0, 2.0 * hs.zeta * w0 * hs.m_kg, w);
    }
    return h;
  }
  if (s.plane != a.plane || s.dir != a.dir) return h;
  const std::string dir(1, s.dir);
  for (const auto& hs : plant.housings) {
    if (hs.plane != s.plane) continue;
    if (std::find(hs.dirs.begin(), hs.dirs.end(), dir) == hs.dirs.end()) continue;
    const double w0 = 2.0 * M_PI * hs.f_hz;
    h += sdof_compliance(hs.m_kg, hs.m_kg * w0 * w0, 2.0 * hs.zeta * w0 * hs.m_kg, w);
  }
  return h;
}

}  // namespace ambdiag::detail
