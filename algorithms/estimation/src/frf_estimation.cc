// FRF estimation from run recordings: channel roles, bad-run checks and the
// dispatch to the estimator of the excitation type.
#include "ambdiag/algorithms/estimation/frf_estimation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "ambdiag/core/error.h"
#include "frf_estimation_internal.h"

namespace ambdiag {

namespace frf_estimation {

namespace {

std::string wrap_unit(const std::string& u) {
  if (u.empty()) return "1";
  return u.find_first_of("/*^ ") == std::string::npos ? u : "(" + u + ")";
}

}  // namespace

std::vector<int> ChannelPlan::measured_channels() const {
  std::vector<int> c = output_channels;
  c.insert(c.end(), input_channels.begin(), input_channels.end());
  return c;
}

ChannelPlan plan_channels(const RunRecording& run) {
  ChannelPlan plan;
  std::vector<int> refs, forces;
  // Responses: displacement first, then velocity, then acceleration; a run
  // that mixes them gets the FRF of the first kind present.
  const ChannelRole response_roles[] = {ChannelRole::displacement, ChannelRole::velocity,
                                        ChannelRole::acceleration};
  const FrfQuantity quantities[] = {FrfQuantity::compliance, FrfQuantity::mobility, FrfQuantity::accelerance};
  for (int k = 0; k < 3 && plan.output_channels.empty(); ++k) {
    for (size_t c = 0; c < run.channels.size(); ++c) {
      if (run.channels[c].role != response_roles[k]) continue;
      plan.output_channels.push_back(static_cast<int>(c));
      plan.outputs.push_back(run.channels[c].name);
      plan.quantity = quantities[k];
    }
  }
  int ignored_responses = 0;
  for (size_t c = 0; c < run.channels.size(); ++c) {
    const Channel& ch = run.channels[c];
    if (ch.role == ChannelRole::reference) refs.push_back(static_cast<int>(c));
    if (ch.role == ChannelRole::force) forces.push_back(static_cast<int>(c));
    const bool response = ch.role == ChannelRole::displacement || ch.role == ChannelRole::velocity ||
                          ch.role == ChannelRole::acceleration;
    if (response && std::find(plan.output_channels.begin(), plan.output_channels.end(),
                              static_cast<int>(c)) == plan.output_channels.end()) {
      ++ignored_responses;
    }
  }
  if (plan.output_channels.empty()) {
    throw InputError("channels: no response channel (role displacement, velocity or acceleration)");
  }
  if (refs.empty()) {
    throw InputError("channels: no reference channel (the injected excitation is needed as the instrument)");
  }
  if (ignored_responses > 0) {
    plan.warnings.push_back(std::to_string(ignored_responses) + " response channel(s) of another kind than " +
                            to_string(plan.quantity) + " ignored");
  }

  if (forces.empty()) {
    // Open loop or a rig without force sensors: H relative to the reference.
    plan.inputs_are_references = true;
    for (int r : refs) {
      plan.inputs.push_back(run.channels[r].input.empty() ? run.channels[r].name : run.channels[r].input);
      plan.input_channels.push_back(r);
      plan.reference_channels.push_back(r);
    }
  } else {
    for (int f : forces) {
      const std::string& name = run.channels[f].name;
      int ref = -1;
      for (int r : refs) {
        if (run.channels[r].input != name) continue;
        if (ref >= 0) {
          throw InputError("channels: references " + run.channels[ref].name + " and " + run.channels[r].name +
                           " both drive " + name);
        }
        ref = r;
      }
      if (ref < 0) {
        throw InputError("channels: force channel " + name +
                         " has no reference channel driving it (role reference, \"input\": \"" + name +
                         "\"); without it the closed-loop FRF cannot be estimated without bias");
      }
      plan.inputs.push_back(name);
      plan.input_channels.push_back(f);
      plan.reference_channels.push_back(ref);
    }
    for (int r : refs) {
      if (std::find(plan.inputs.begin(), plan.inputs.end(), run.channels[r].input) == plan.inputs.end()) {
        throw InputError("channels: reference " + run.channels[r].name + " drives " + run.channels[r].input +
                         ", but no force channel of that name is recorded");
      }
    }
  }

  const auto common_unit = [&](const std::vector<int>& chans, const char* what) {
    const std::string& u = run.channels[chans.front()].unit;
    for (int c : chans) {
      if (run.channels[c].unit != u) {
        throw InputError("channels: " + std::string(what) + " channels " + run.channels[chans.front()].name +
                         " and " + run.channels[c].name + " have different units ('" + u + "', '" +
                         run.channels[c].unit + "')");
      }
    }
    return u;
  };
  const std::string out_unit = common_unit(plan.output_channels, "response");
  const std::string in_unit = common_unit(plan.input_channels, "input");
  plan.unit = wrap_unit(out_unit) + "/" + wrap_unit(in_unit);
  return plan;
}

double channel_rms(const RunRecording& run, int channel, int64_t begin, int64_t end) {
  double s = 0.0;
  for (int64_t t = begin; t < end; ++t) {
    const double v = run.at(t, channel);
    s += v * v;
  }
  return end > begin ? std::sqrt(s / static_cast<double>(end - begin)) : 0.0;
}

void check_clipping(const RunRecording& run, const ChannelPlan& plan, const Windows& windows) {
  std::vector<int> chans = plan.output_channels;
  if (!plan.inputs_are_references)
    chans.insert(chans.end(), plan.input_channels.begin(), plan.input_channels.end());
  for (int c : chans) {
    float lo = run.at(windows.front().first, c), hi = lo;
    for (const auto& [b, e] : windows) {
      for (int64_t t = b; t < e; ++t) {
        lo = std::min(lo, run.at(t, c));
        hi = std::max(hi, run.at(t, c));
      }
    }
    const std::string& name = run.channels[static_cast<size_t>(c)].name;
    if (lo == hi) {
      throw InputError("channel " + name + ": constant (" + format_number(lo) +
                       ") over the excitation: a dead sensor or a disconnected signal");
    }
    // Samples in runs of >= 3 equal values at the extremes: a saturated
    // converter or amplifier (noise makes such runs vanishingly rare).
    long stuck = 0;
    int64_t first = -1;
    const auto flush = [&](int64_t run_len, int64_t end) {
      if (run_len < 3) return;
      stuck += run_len;
      if (first < 0) first = end - run_len;
    };
    for (const auto& [b, e] : windows) {
      int64_t run_len = 0;
      for (int64_t t = b; t < e; ++t) {
        const float v = run.at(t, c);
        const bool extreme = v == lo || v == hi;
        if (extreme && run_len > 0 && v == run.at(t - 1, c)) {
          ++run_len;
        } else {
          flush(run_len, t);
          run_len = extreme ? 1 : 0;
        }
      }
      flush(run_len, e);
    }
    if (stuck > 0) {
      throw InputError("channel " + name + ": clipped: " + std::to_string(stuck) +
                       " samples stuck at its extreme values (" + format_number(lo) + ", " +
                       format_number(hi) + "), first at frame " + std::to_string(first) +
                       "; the estimate would be biased (reduce the excitation or the gain)");
    }
  }
}

void check_references(const RunRecording& run, const ChannelPlan& plan, const Windows& windows) {
  std::vector<double> rms;
  for (int r : plan.reference_channels) {
    double s = 0.0;
    int64_t n = 0;
    for (const auto& [b, e] : windows) {
      const double x = channel_rms(run, r, b, e);
      s += x * x * static_cast<double>(e - b);
      n += e - b;
    }
    rms.push_back(n > 0 ? std::sqrt(s / static_cast<double>(n)) : 0.0);
  }
  const double top = *std::max_element(rms.begin(), rms.end());
  for (size_t i = 0; i < rms.size(); ++i) {
    if (rms[i] > 1e-6 * top && top > 0.0) continue;
    const Channel& ch = run.channels[static_cast<size_t>(plan.reference_channels[i])];
    throw InputError("reference channel " + ch.name + " (input " + ch.input +
                     ") is zero over the excitation (rms " + format_number(rms[i]) + " " + ch.unit +
                     "): input " + plan.inputs[i] + " is not excited and its FRFs cannot be estimated");
  }
}

double median_excited_power(const std::vector<double>& power, double fraction) {
  if (power.empty()) return 0.0;
  const double max_power = *std::max_element(power.begin(), power.end());
  std::vector<double> excited;
  for (double x : power) {
    if (x > fraction * max_power) excited.push_back(x);
  }
  if (excited.empty()) return 0.0;
  std::nth_element(excited.begin(), excited.begin() + static_cast<long>(excited.size() / 2), excited.end());
  return excited[excited.size() / 2];
}

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string describe_lines(const std::vector<double>& freq_hz) {
  std::string s = std::to_string(freq_hz.size()) + (freq_hz.size() == 1 ? " line (" : " lines (");
  const size_t shown = std::min<size_t>(freq_hz.size(), 6);
  for (size_t k = 0; k < shown; ++k) s += (k ? ", " : "") + format_number(freq_hz[k]);
  if (shown < freq_hz.size()) s += ", ... " + format_number(freq_hz.back());
  return s + " Hz)";
}

}  // namespace frf_estimation

std::string FrfEstimationOptions::invalid_reason() const {
  if (nfft != 0 && (nfft < 4 || nfft % 2 != 0)) return "nfft: must be 0 (automatic) or an even number >= 4";
  if (!(min_rcond >= 0.0 && min_rcond < 1.0)) return "min_rcond: must be in [0, 1)";
  if (!(warn_rcond >= min_rcond && warn_rcond < 1.0)) return "warn_rcond: must be in [min_rcond, 1)";
  return {};
}

FrfEstimate estimate_frf(const RunRecording& run, const FrfEstimationOptions& options) {
  if (const std::string why = options.invalid_reason(); !why.empty()) throw InputError(why);
  if (!run.excitation || run.excitation->type == ExcitationType::none || run.excitation->segments.empty()) {
    throw InputError("excitation: none recorded (kind " + run.kind + "): there is no FRF to estimate");
  }
  if (run.channels.empty() || run.frame_count() == 0) throw InputError("samples: the run holds no frames");
  const frf_estimation::ChannelPlan plan = frf_estimation::plan_channels(run);
  FrfEstimate est;
  switch (run.excitation->type) {
    case ExcitationType::multisine:
      est = estimate_multisine(run, plan, options);
      break;
    case ExcitationType::stepsine:
      est = estimate_stepsine(run, plan, options);
      break;
    case ExcitationType::chirp:
    case ExcitationType::random: {
      NonperiodicMethod m = options.method;
      if (m == NonperiodicMethod::automatic) {
        m = run.excitation->type == ExcitationType::chirp ? NonperiodicMethod::gated
                                                          : NonperiodicMethod::welch;
      }
      if (m == NonperiodicMethod::gated) {
        est = estimate_gated(run, plan, options);
      } else if (m == NonperiodicMethod::lpm) {
        est = estimate_lpm(run, plan, options);
      } else {
        est = estimate_welch(run, plan, options);
      }
      break;
    }
    case ExcitationType::none:
      break;
  }
  est.warnings.insert(est.warnings.begin(), plan.warnings.begin(), plan.warnings.end());

  FrfData& frf = est.frf;
  frf.set_meta("pump_id", run.pump_id);
  frf.set_meta("run_id", run.run_id);
  frf.speed_rpm = run.speed_rpm;
  frf.quantity = plan.quantity;
  frf.unit = plan.unit;
  frf.set_meta("method", est.method);
  frf.set_meta("excitation", to_string(run.excitation->type));
  frf.set_meta("averages", std::to_string(est.averages));
  if (est.sigma_dof > 0) frf.set_meta("sigma_dof", std::to_string(est.sigma_dof));
  // The FRF file's metadata keys are unique: number the warnings.
  for (size_t k = 0; k < est.warnings.size(); ++k)
    frf.set_meta("warning_" + std::to_string(k + 1), est.warnings[k]);
  return est;
}

}  // namespace ambdiag
