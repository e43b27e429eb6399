#include "frf_terms.h"

#include <algorithm>
#include <string>

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

namespace {

// The single-DOF systems (m, k, c) in parallel between s and a.
struct Sdof {
  double m_kg, k_n_per_m, c_ns_per_m;
};

std::vector<Sdof> parallel_sdofs(const PlantModel& plant, const MeasurementPoint& s, const MeasurementPoint& a) {
  std::vector<Sdof> out;
  auto housing = [&](double m_kg, double f_hz, double zeta) {
    const double w0 = 2.0 * M_PI * f_hz;
    out.push_back({m_kg, m_kg * w0 * w0, 2.0 * zeta * w0 * m_kg});
  };
  if (s.is_axial() != a.is_axial()) return out;
  if (s.is_axial()) {
    const AxialModel& ax = *plant.axial;
    out.push_back({ax.m_kg.value_or(plant.rotor_mass_kg()), ax.k_n_per_m, ax.c_ns_per_m});
    for (const auto& hs : ax.housings) housing(hs.m_kg, hs.f_hz, hs.zeta);
    return out;
  }
  if (s.plane != a.plane || s.dir != a.dir) return out;
  const std::string dir(1, s.dir);
  for (const auto& hs : plant.housings) {
    if (hs.plane != s.plane) continue;
    if (std::find(hs.dirs.begin(), hs.dirs.end(), dir) == hs.dirs.end()) continue;
    housing(hs.m_kg, hs.f_hz, hs.zeta);
  }
  return out;
}

}  // namespace

std::vector<std::complex<double>> parallel_compliances(const PlantModel& plant, const MeasurementPoint& s,
                                                       const MeasurementPoint& a, const std::vector<double>& w) {
  std::vector<std::complex<double>> h(w.size(), 0.0);
  for (const Sdof& d : parallel_sdofs(plant, s, a))
    for (size_t l = 0; l < w.size(); ++l) h[l] += sdof_compliance(d.m_kg, d.k_n_per_m, d.c_ns_per_m, w[l]);
  return h;
}

}  // namespace ambdiag::detail
