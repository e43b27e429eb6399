#include "ambdiag/algorithms/model/frf_synthesis.h"

#include <chrono>
#include <cmath>
#include <string>

#include "ambdiag/core/error.h"
#include "frf_lateral.h"
#include "frf_terms.h"

namespace ambdiag {

std::vector<double> frequency_grid(double fmin_hz, double fmax_hz, double df_hz) {
  if (!(fmin_hz > 0) || !std::isfinite(fmin_hz)) throw InputError("--fmin: must be > 0");
  if (!(fmax_hz >= fmin_hz) || !std::isfinite(fmax_hz)) throw InputError("--fmax: must be >= fmin");
  if (!(df_hz > 0) || !std::isfinite(df_hz)) throw InputError("--df: must be > 0");
  const double count = std::floor((fmax_hz - fmin_hz) / df_hz + 0.5) + 1;
  if (count > 1e7) throw InputError("frequency grid: more than 10 million lines");
  std::vector<double> f;
  for (int64_t i = 0; i < static_cast<int64_t>(count); ++i) f.push_back(fmin_hz + static_cast<double>(i) * df_hz);
  return f;
}

namespace detail {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double seconds_since(double start_s) { return now_s() - start_s; }

}  // namespace detail

FrfData synthesize_frf(const PlantModel& plant, double speed_rpm, const std::vector<double>& freq_hz,
                       const FrfSynthesisOptions& options, FrfReport* report) {
  if (plant.sensors.empty() || plant.actuators.empty()) throw InputError("an FRF needs sensors and actuators in the model");
  for (size_t i = 0; i < freq_hz.size(); ++i) {
    if (!(freq_hz[i] > 0) || !std::isfinite(freq_hz[i])) throw InputError("frequency " + std::to_string(i) + ": must be > 0");
    if (i > 0 && !(freq_hz[i] > freq_hz[i - 1])) throw InputError("frequencies must be strictly increasing");
  }
  std::vector<double> w(freq_hz.size());
  for (size_t i = 0; i < w.size(); ++i) w[i] = 2.0 * M_PI * freq_hz[i];

  if (!(options.krylov_tol > 0.0)) throw InputError("krylov_tol: must be > 0");
  FrfReport rep;
  const double t0 = detail::now_s();
  StructuralDampingOptions damping = options.damping;
  if (!w.empty()) damping.omega_max_rad_per_s = w.back();
  const RotorSystem sys = assemble_rotor(plant, speed_rpm, damping);
  rep.damping_modes_per_plane = sys.damping_modes_per_plane;
  rep.damping_cutoff_hz = sys.damping_cutoff_rad_per_s / (2.0 * M_PI);
  const detail::LateralMaps maps = detail::lateral_maps(plant, sys);
  rep.assembly_s = detail::seconds_since(t0);
  constexpr int kAllModesMaxStates = 400;
  Eigen::MatrixXcd lat;
  if (options.method == FrfMethod::direct) {
    lat = detail::lateral_frf_direct(sys, maps, w, rep);
  } else if (options.modal_basis == ModalBasis::all) {
    lat = detail::lateral_frf_modal(sys, maps, w, rep);
  } else {
    lat = detail::lateral_frf_modal_krylov(sys, maps, w, options.krylov_tol, rep);
    if (!rep.converged && options.modal_basis == ModalBasis::automatic && 2 * sys.size() <= kAllModesMaxStates) {
      // A small system whose Krylov basis fell short: every eigenvalue.
      FrfReport all;
      all.damping_modes_per_plane = rep.damping_modes_per_plane;
      all.damping_cutoff_hz = rep.damping_cutoff_hz;
      all.assembly_s = rep.assembly_s;
      lat = detail::lateral_frf_modal(sys, maps, w, all);
      all.setup_s += rep.setup_s + rep.lines_s;  // the Krylov attempt
      rep = all;
    }
  }

  FrfData out;
  out.freq_hz = freq_hz;
  out.speed_rpm = speed_rpm;
  out.set_meta("speed_rpm", std::to_string(speed_rpm));
  out.set_meta("quantity", "compliance");
  out.set_meta("unit", "m/N");
  out.set_meta("source", "ambdiag model frf (" + std::string(options.method == FrfMethod::modal ? "modal" : "direct") + ")");
  if (rep.krylov_size > 0) out.set_meta("krylov_residual", std::to_string(rep.krylov_residual));
  // Position of each sensor/actuator among the lateral ones (-1: axial).
  std::vector<int> lat_out(plant.sensors.size(), -1), lat_in(plant.actuators.size(), -1);
  for (size_t k = 0; k < maps.sensor_index.size(); ++k) lat_out[static_cast<size_t>(maps.sensor_index[k])] = static_cast<int>(k);
  for (size_t k = 0; k < maps.actuator_index.size(); ++k) lat_in[static_cast<size_t>(maps.actuator_index[k])] = static_cast<int>(k);
  const Eigen::Index n_in_lat = static_cast<Eigen::Index>(maps.actuator_index.size());

  for (size_t o = 0; o < plant.sensors.size(); ++o) {
    for (size_t i = 0; i < plant.actuators.size(); ++i) {
      FrfEntry e;
      e.output = plant.sensors[o].name;
      e.input = plant.actuators[i].name;
      e.h = detail::parallel_compliances(plant, plant.sensors[o], plant.actuators[i], w);
      if (lat_out[o] >= 0 && lat_in[i] >= 0) {
        const auto col = lat.col(lat_out[o] * n_in_lat + lat_in[i]);
        for (size_t line = 0; line < freq_hz.size(); ++line) e.h[line] += col(static_cast<Eigen::Index>(line));
      }
      out.entries.push_back(std::move(e));
    }
  }
  if (report) *report = rep;
  return out;
}

}  // namespace ambdiag
