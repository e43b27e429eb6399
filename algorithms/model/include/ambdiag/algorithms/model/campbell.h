// Campbell diagram: the lateral rotor modes followed over a speed range,
// their critical speeds (crossings with the synchronous line f = rpm / 60)
// and their stability (log decrement).
//
// At each speed the modes come from modal_analysis (links at that speed from
// their tables). A mode is paired with the tracks of the previous speed by
// its mode shape, never by frequency order: the score of a pair is the
// modal assurance criterion of the full complex shapes
//   MAC(a, b) = |a^H b|^2 / ((a^H a) (b^H b)),
// with closeness to the track's linearly extrapolated frequency as a small
// tie-breaker, and pairs are taken greedily by best score. Within a group
// of repeated eigenvalues (an isotropic rotor at standstill) any basis of
// the eigenspace is valid, so there the MAC is taken against the group's
// subspace. Crossing tracks (a forward mode rising through a backward one,
// whose shapes are orthogonal) are therefore followed through the crossing.
//
// Tracked: rotor modes (kind "rotor") that are not overdamped and have
// f_hz > 0. Housing and axial modes do not depend on speed; they are listed
// in `fixed_modes` (drawn as flat lines) and have no critical speeds here.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "ambdiag/algorithms/model/modal_analysis.h"
#include "ambdiag/core/plant_model.h"

namespace ambdiag {

struct CampbellOptions {
  double speed_min_rpm = 0.0;
  double speed_max_rpm = 3000.0;
  int n_speeds = 31;         // equally spaced, >= 2 (1 if min == max)
  double f_max_hz = 1000.0;  // tracks are reported if they come below this
  // A pair whose MAC is below this is not a continuation: the track ends and
  // the mode starts a new one (e.g. modes entering or leaving the band).
  double min_mac = 0.3;
};

// One mode followed over the speeds. Entries are NaN (whirl none) at
// speeds where the track does not exist.
struct CampbellTrack {
  std::string label;          // "1F", "2B", ...: whirl and rank among tracks of that whirl
  Whirl whirl = Whirl::none;  // the track's whirl (majority over speeds > 0)
  std::vector<double> f_hz;
  std::vector<double> zeta;
  std::vector<double> log_dec;
  std::vector<Whirl> whirl_at;  // per speed; at a repeated eigenvalue, the track's whirl
  std::vector<double> mac;      // MAC with the previous speed's shape (NaN at the first)
  double min_log_dec = 0.0;     // over the speeds where the track exists
  double min_log_dec_speed_rpm = 0.0;
  // First speed where the log decrement becomes negative (below -1e-5, so
  // that round-off of an undamped mode does not count), interpolated
  // linearly between speed steps; empty if the track stays stable.
  std::optional<double> instability_onset_rpm;
};

// A crossing of a track with the 1x line, interpolated linearly between the
// two speed steps that bracket it.
struct CriticalSpeed {
  double speed_rpm = 0.0;
  double f_hz = 0.0;  // = speed_rpm / 60
  int track = 0;      // index into CampbellResult::tracks
  std::string label;
  Whirl whirl = Whirl::none;
  double log_dec = 0.0;
};

struct FixedMode {
  std::string label, kind;  // kind "housing", "axial", "axial_housing"
  double f_hz = 0.0;
  double zeta = 0.0;
};

struct CampbellResult {
  std::vector<double> speeds_rpm;
  std::vector<CampbellTrack> tracks;           // ordered by frequency at their first speed
  std::vector<CriticalSpeed> critical_speeds;  // ascending speed
  std::vector<FixedMode> fixed_modes;
  double f_max_hz = 0.0;
  bool stable = true;                           // every tracked mode has log_dec >= -1e-5 at every speed
  std::optional<double> instability_onset_rpm;  // lowest over the tracks
  double worst_mac = 1.0;                       // weakest accepted pairing: tracking quality
};

// Throws InputError for invalid options or an invalid plant model.
CampbellResult campbell(const PlantModel& plant, const CampbellOptions& options);

// Frequency over speed (forward solid, backward dashed, the 1x line, critical
// speeds as markers, radial housing modes grey) over a log decrement panel.
std::string campbell_svg(const CampbellResult& result, const std::string& title = "Campbell diagram");
// Missing entries (NaN) are written as null.
nlohmann::json campbell_to_json(const CampbellResult& result);

}  // namespace ambdiag
