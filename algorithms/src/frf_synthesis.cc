#include "ambdiag/algorithms/frf_synthesis.h"

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

FrfData synthesize_frf(const PlantModel& plant, double speed_rpm, const std::vector<double>& freq_hz,
                       const FrfSynthesisOptions& options) {
  if (plant.sensors.empty() || plant.actuators.empty()) throw InputError("an FRF needs sensors and actuators in the model");
  for (size_t i = 0; i < freq_hz.size(); ++i) {
    if (!(freq_hz[i] > 0) || !std::isfinite(freq_hz[i])) throw InputError("frequency " + std::to_string(i) + ": must be > 0");
    if (i > 0 && !(freq_hz[i] > freq_hz[i - 1])) throw InputError("frequencies must be strictly increasing");
  }
  std::vector<double> w(freq_hz.size());
  for (size_t i = 0; i < w.size(); ++i) w[i] = 2.0 * M_PI * freq_hz[i];

  const RotorSystem sys = assemble_rotor(plant, speed_rpm);
  const detail::LateralMaps maps = detail::lateral_maps(plant, sys);
  const Eigen::MatrixXcd lat = options.method == FrfMethod::modal ? detail::lateral_frf_modal(sys, maps, w)
                                                                  : detail::lateral_frf_direct(sys, maps, w);

  FrfData out;
  out.freq_hz = freq_hz;
  out.speed_rpm = speed_rpm;
  out.set_meta("speed_rpm", std::to_string(speed_rpm));
  out.set_meta("quantity", "compliance");
  out.set_meta("unit", "m/N");
  out.set_meta("source", "ambdiag model frf (" + std::string(options.method == FrfMethod::modal ? "modal" : "direct") + ")");
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
      e.h.resize(freq_hz.size());
      for (size_t line = 0; line < freq_hz.size(); ++line) {
        std::complex<double> v = detail::parallel_compliance(plant, plant.sensors[o], plant.actuators[i], w[line]);
        if (lat_out[o] >= 0 && lat_in[i] >= 0) v += lat(static_cast<Eigen::Index>(line), lat_out[o] * n_in_lat + lat_in[i]);
        e.h[line] = v;
      }
      out.entries.push_back(std::move(e));
    }
  }
  return out;
}

}  // namespace ambdiag
