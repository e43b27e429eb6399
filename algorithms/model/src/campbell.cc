#include "ambdiag/algorithms/model/campbell.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "ambdiag/core/error.h"

namespace ambdiag {

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
// Modes are followed up to this multiple of f_max so that a track does not
// break where it leaves the band of interest; tracks that never come below
// f_max are dropped at the end.
constexpr double kBandMargin = 1.5;
// Eigenvalues this close (relative) are one repeated eigenvalue. The
// first-order eigensolver resolves a repeated pair to ~1e-6 only, and within
// such a gap the individual eigenvectors are ill-determined anyway.
constexpr double kRepeatedTol = 1e-4;
// Log decrements within this of zero are round-off of an undamped mode, not
// an instability.
constexpr double kNeutralLogDec = 1e-5;
// Weight of the frequency tie-breaker against MAC (0..1).
constexpr double kFreqWeight = 0.01;

void check_options(const CampbellOptions& o) {
  auto fail = [](const std::string& what) { throw InputError("campbell options: " + what); };
  if (!std::isfinite(o.speed_min_rpm) || o.speed_min_rpm < 0) fail("speed_min_rpm: must be >= 0");
  if (!std::isfinite(o.speed_max_rpm) || o.speed_max_rpm < o.speed_min_rpm) {
    fail("speed_max_rpm: must be >= speed_min_rpm");
  }
  if (o.n_speeds < 1 || o.n_speeds > 10000) fail("n_speeds: must be in 1..10000");
  if (o.n_speeds == 1 && o.speed_max_rpm != o.speed_min_rpm) fail("n_speeds: must be >= 2 for a speed range");
  if (o.n_speeds > 1 && !(o.speed_max_rpm > o.speed_min_rpm)) fail("speed_max_rpm: must be > speed_min_rpm");
  if (!std::isfinite(o.f_max_hz) || !(o.f_max_hz > 0)) fail("f_max_hz: must be > 0");
  if (!(o.min_mac >= 0.0 && o.min_mac <= 1.0)) fail("min_mac: must be in [0, 1]");
}

double mac(const Eigen::VectorXcd& a, const Eigen::VectorXcd& b) {
  const double den = a.squaredNorm() * b.squaredNorm();
  return den > 0 ? std::norm(a.dot(b)) / den : 0.0;
}

// A tracked mode at one speed, with what the next step needs.
struct Point {
  const Mode* mode = nullptr;
  int group = -1;  // index of its repeated-eigenvalue group at this speed, -1: simple
};

// Tracked modes of one speed, with repeated eigenvalues grouped.
std::vector<Point> tracked_points(const ModalResult& r, double f_limit_hz,
                                  std::vector<Eigen::MatrixXcd>& groups) {
  std::vector<Point> pts;
  for (const auto& m : r.modes) {
    if (m.kind == "rotor" && !m.overdamped && m.f_hz > 0.0 && m.f_hz <= f_limit_hz && m.shape.size() > 0) {
      pts.push_back({&m, -1});
    }
  }
  groups.clear();
  for (size_t a = 0; a < pts.size(); ++a) {
    if (pts[a].group >= 0) continue;
    std::vector<size_t> members{a};
    for (size_t b = a + 1; b < pts.size(); ++b) {
      const auto la = pts[a].mode->eigenvalue, lb = pts[b].mode->eigenvalue;
      if (pts[b].group < 0 && std::abs(la - lb) <= kRepeatedTol * std::abs(la)) members.push_back(b);
    }
    if (members.size() < 2) continue;
    Eigen::MatrixXcd s(pts[a].mode->shape.size(), static_cast<Eigen::Index>(members.size()));
    for (size_t k = 0; k < members.size(); ++k) {
      s.col(static_cast<Eigen::Index>(k)) = pts[members[k]].mode->shape;
      pts[members[k]].group = static_cast<int>(groups.size());
    }
    // Orthonormal basis of the eigenspace.
    Eigen::HouseholderQR<Eigen::MatrixXcd> qr(s);
    groups.push_back(qr.householderQ() * Eigen::MatrixXcd::Identity(s.rows(), s.cols()));
  }
  return pts;
}

// Live state of a track between two speeds.
struct Live {
  int track = 0;
  Eigen::MatrixXcd shape;  // one column, or an orthonormal basis of a repeated eigenspace
  int group = -1;
  double f_pred_hz = 0.0;  // extrapolated to the next speed
};

struct TrackData {
  CampbellTrack t;
  std::vector<bool> repeated;  // at a repeated eigenvalue: whirl undefined
};

void append(TrackData& d, size_t at, const Mode& m, double pair_mac, bool repeated) {
  d.t.f_hz[at] = m.f_hz;
  d.t.zeta[at] = m.zeta;
  d.t.log_dec[at] = m.log_decrement();
  d.t.whirl_at[at] = m.whirl;
  d.t.mac[at] = pair_mac;
  d.repeated[at] = repeated;
}

TrackData new_track(size_t n) {
  TrackData d;
  d.t.f_hz.assign(n, kNan);
  d.t.zeta.assign(n, kNan);
  d.t.log_dec.assign(n, kNan);
  d.t.whirl_at.assign(n, Whirl::none);
  d.t.mac.assign(n, kNan);
  d.repeated.assign(n, false);
  return d;
}

// Majority whirl over the speeds > 0 where the eigenvalue is simple.
Whirl track_whirl(const TrackData& d, const std::vector<double>& speeds) {
  int fwd = 0, bwd = 0;
  for (int pass = 0; pass < 2 && fwd + bwd == 0; ++pass) {
    for (size_t i = 0; i < speeds.size(); ++i) {
      if (std::isnan(d.t.f_hz[i]) || (pass == 0 && (speeds[i] == 0.0 || d.repeated[i]))) continue;
      fwd += d.t.whirl_at[i] == Whirl::forward;
      bwd += d.t.whirl_at[i] == Whirl::backward;
    }
  }
  if (fwd + bwd == 0) return Whirl::none;
  return fwd >= bwd ? Whirl::forward : Whirl::backward;
}

void stability(CampbellTrack& t, const std::vector<double>& speeds) {
  bool any = false;
  for (size_t i = 0; i < speeds.size(); ++i) {
    const double ld = t.log_dec[i];
    if (std::isnan(ld)) continue;
    if (!any || ld < t.min_log_dec) {
      t.min_log_dec = ld;
      t.min_log_dec_speed_rpm = speeds[i];
    }
    if (ld < -kNeutralLogDec && !t.instability_onset_rpm) {
      const bool prev = i > 0 && !std::isnan(t.log_dec[i - 1]);
      // Zero of the log decrement between the last stable and first unstable step.
      const double u = prev ? std::clamp(t.log_dec[i - 1] / (t.log_dec[i - 1] - ld), 0.0, 1.0) : 1.0;
      t.instability_onset_rpm = prev ? speeds[i - 1] + u * (speeds[i] - speeds[i - 1]) : speeds[i];
    }
    any = true;
  }
}

void critical_speeds(const CampbellResult& r, int ti, std::vector<CriticalSpeed>& out) {
  const auto& t = r.tracks[static_cast<size_t>(ti)];
  const auto& s = r.speeds_rpm;
  auto add = [&](size_t i, double u) {  // crossing at s[i] + u (s[i+1] - s[i])
    const size_t j = std::min(i + 1, s.size() - 1);
    CriticalSpeed c;
    c.speed_rpm = s[i] + u * (s[j] - s[i]);
    c.f_hz = c.speed_rpm / 60.0;
    c.track = ti;
    c.label = t.label;
    c.log_dec = t.log_dec[i] + u * (t.log_dec[j] - t.log_dec[i]);
    c.whirl = t.whirl_at[u <= 0.5 ? i : j];
    out.push_back(c);
  };
  for (size_t i = 0; i < s.size(); ++i) {
    if (std::isnan(t.f_hz[i])) continue;
    const double g0 = t.f_hz[i] - s[i] / 60.0;  // above (+) or below (-) the 1x line
    if (g0 == 0.0) {
      add(i, 0.0);
      continue;
    }
    if (i + 1 >= s.size() || std::isnan(t.f_hz[i + 1])) continue;
    const double g1 = t.f_hz[i + 1] - s[i + 1] / 60.0;
    if (g0 * g1 < 0.0) add(i, g0 / (g0 - g1));
  }
}

}  // namespace

CampbellResult campbell(const PlantModel& plant, const CampbellOptions& opt) {
  check_options(opt);
  validate_plant(plant);
  CampbellResult r;
  r.f_max_hz = opt.f_max_hz;
  const size_t n = static_cast<size_t>(opt.n_speeds);
  for (size_t i = 0; i < n; ++i) {
    r.speeds_rpm.push_back(n == 1
                               ? opt.speed_min_rpm
                               : opt.speed_min_rpm + (opt.speed_max_rpm - opt.speed_min_rpm) *
                                                         static_cast<double>(i) / static_cast<double>(n - 1));
  }

  ModalOptions mo;
  mo.overdamped = false;
  mo.shapes = true;
  std::vector<TrackData> tracks;
  std::vector<Live> live;
  for (size_t i = 0; i < n; ++i) {
    const ModalResult modal = modal_analysis(plant, r.speeds_rpm[i], mo);
    if (i == 0) {
      for (const auto& m : modal.modes) {
        if (m.kind != "rotor") r.fixed_modes.push_back({m.label, m.kind, m.f_hz, m.zeta});
      }
    }
    std::vector<Eigen::MatrixXcd> groups;
    const std::vector<Point> pts = tracked_points(modal, kBandMargin * opt.f_max_hz, groups);

    // Candidate pairs (score, MAC, live index, point index), best first.
    std::vector<std::tuple<double, double, size_t, size_t>> pairs;
    for (size_t a = 0; a < live.size(); ++a) {
      for (size_t b = 0; b < pts.size(); ++b) {
        const Eigen::VectorXcd& s = pts[b].mode->shape;
        // At a repeated eigenvalue the track's shape is one arbitrary vector of
        // the eigenspace: compare with the space.
        const double m = live[a].group >= 0
                             ? (live[a].shape.adjoint() * s).squaredNorm() / std::max(s.squaredNorm(), 1e-300)
                             : mac(live[a].shape.col(0), s);
        if (m < opt.min_mac) continue;
        const double df = std::abs(pts[b].mode->f_hz - live[a].f_pred_hz) / std::max(live[a].f_pred_hz, 1e-9);
        pairs.emplace_back(m - kFreqWeight * std::min(df, 1.0), m, a, b);
      }
    }
    std::sort(pairs.begin(), pairs.end(),
              [](const auto& x, const auto& y) { return std::get<0>(x) > std::get<0>(y); });
    std::vector<int> point_track(pts.size(), -1);
    std::vector<double> point_mac(pts.size(), kNan);
    std::vector<bool> live_used(live.size(), false);
    for (const auto& [score, m, a, b] : pairs) {
      if (live_used[a] || point_track[b] >= 0) continue;
      live_used[a] = true;
      point_track[b] = live[a].track;
      point_mac[b] = m;
      r.worst_mac = std::min(r.worst_mac, m);
    }

    std::vector<Live> next;
    for (size_t b = 0; b < pts.size(); ++b) {
      if (point_track[b] < 0) {
        point_track[b] = static_cast<int>(tracks.size());
        tracks.push_back(new_track(n));
      }
      TrackData& d = tracks[static_cast<size_t>(point_track[b])];
      const Mode& m = *pts[b].mode;
      append(d, i, m, point_mac[b], pts[b].group >= 0);
      Live l;
      l.track = point_track[b];
      l.group = pts[b].group;
      l.shape = l.group >= 0 ? groups[static_cast<size_t>(l.group)] : Eigen::MatrixXcd(m.shape);
      const double f_prev = i > 0 ? d.t.f_hz[i - 1] : kNan;
      l.f_pred_hz = std::isnan(f_prev) ? m.f_hz : std::max(2.0 * m.f_hz - f_prev, 0.0);
      next.push_back(std::move(l));
    }
    live = std::move(next);
  }

  // Keep tracks that come into the band; order them by their first frequency.
  std::erase_if(tracks, [&](const TrackData& d) {
    return std::none_of(d.t.f_hz.begin(), d.t.f_hz.end(), [&](double f) { return f <= opt.f_max_hz; });
  });
  auto first = [](const TrackData& d) {
    size_t i = 0;
    while (std::isnan(d.t.f_hz[i])) ++i;
    return std::make_pair(i, d.t.f_hz[i]);
  };
  std::stable_sort(tracks.begin(), tracks.end(),
                   [&](const TrackData& a, const TrackData& b) { return first(a) < first(b); });
  int n_fwd = 0, n_bwd = 0, n_other = 0;
  for (auto& d : tracks) {
    CampbellTrack& t = d.t;
    t.whirl = track_whirl(d, r.speeds_rpm);
    switch (t.whirl) {
      case Whirl::forward:
        t.label = std::to_string(++n_fwd) + "F";
        break;
      case Whirl::backward:
        t.label = std::to_string(++n_bwd) + "B";
        break;
      case Whirl::none:
        t.label = "mode " + std::to_string(++n_other);
        break;
    }
    for (size_t i = 0; i < n; ++i)
      if (d.repeated[i]) t.whirl_at[i] = t.whirl;
    stability(t, r.speeds_rpm);
    if (t.min_log_dec < -kNeutralLogDec) r.stable = false;
    if (t.instability_onset_rpm &&
        (!r.instability_onset_rpm || *t.instability_onset_rpm < *r.instability_onset_rpm)) {
      r.instability_onset_rpm = t.instability_onset_rpm;
    }
    r.tracks.push_back(std::move(t));
  }
  for (size_t ti = 0; ti < r.tracks.size(); ++ti) critical_speeds(r, static_cast<int>(ti), r.critical_speeds);
  std::stable_sort(r.critical_speeds.begin(), r.critical_speeds.end(),
                   [](const CriticalSpeed& a, const CriticalSpeed& b) { return a.speed_rpm < b.speed_rpm; });
  return r;
}

}  // namespace ambdiag
