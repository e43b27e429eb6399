// Private pieces shared by the FRF estimators (frf_estimation.h): which
// channels are inputs, outputs and instruments, the bad-run checks, the
// per-line instrumental-variable solve and the assembly of the FrfData.
#pragma once

#include <complex>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "ambdiag/algorithms/estimation/frf_estimation.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/core/run_recording.h"

namespace ambdiag::frf_estimation {

struct ChannelPlan {
  std::vector<std::string> outputs;  // response channel names
  std::vector<std::string> inputs;   // actuator names (force channels, or the references' `input`)
  std::vector<int> output_channels;
  std::vector<int> input_channels;      // force channels; the references when inputs_are_references
  std::vector<int> reference_channels;  // reference_channels[i] drives inputs[i]
  bool inputs_are_references = false;
  FrfQuantity quantity = FrfQuantity::compliance;
  std::string unit;
  std::vector<std::string> warnings;

  int n_out() const { return static_cast<int>(outputs.size()); }
  int n_in() const { return static_cast<int>(inputs.size()); }
  // Outputs then inputs (the order of Experiment::z).
  std::vector<int> measured_channels() const;
};

// Throws InputError if the run has no response or reference channels, a
// force channel has no reference, or units disagree.
ChannelPlan plan_channels(const RunRecording& run);

// Sample windows [begin, end) in frames.
using Windows = std::vector<std::pair<int64_t, int64_t>>;

// Throws InputError naming the channel if it holds a run of >= 3 equal
// samples at its extreme value within the windows (a saturated ADC or
// amplifier).
void check_clipping(const RunRecording& run, const ChannelPlan& plan, const Windows& windows);
// Throws InputError naming the channel if a reference is zero (or 1e-6 of
// the largest reference) over the windows: its input is not excited.
void check_references(const RunRecording& run, const ChannelPlan& plan, const Windows& windows);

// RMS of a channel over a window.
double channel_rms(const RunRecording& run, int channel, int64_t begin, int64_t end);

// One experiment at one line.
struct Experiment {
  Eigen::VectorXcd z;    // spectra of the outputs then the inputs
  Eigen::VectorXcd r;    // spectra of the references, one per input
  Eigen::MatrixXcd cov;  // covariance of z's error (as averaged); empty if unknown
  double averages = 1.0;
};

struct LineSolution {
  Eigen::MatrixXcd h;     // n_out x n_in
  Eigen::MatrixXd sigma;  // n_out x n_in; empty if any experiment has no covariance
  double rcond = 0.0;     // of F (n_in x experiments), rows scaled; 0 if singular
};

// H = S_xr S_fr^-1 and sigma by (2) of frf_estimation.h. rcond is the
// reciprocal 2-norm condition number of the measured input spectra F (rows
// scaled to unit norm): how independent the experiments are, the noise
// amplification of X F^-1; h is empty when the solve is impossible.
LineSolution solve_line(const std::vector<Experiment>& experiments, int n_out, int n_in);

// Reciprocal 2-norm condition number of a matrix after scaling its rows to
// unit norm (inputs differ in unit and amplitude; the experiments' own
// amplitudes are information and stay); 0 if a row is zero.
double row_scaled_rcond(const Eigen::MatrixXcd& a);

// coh = |H|^2 / (|H|^2 + n sigma^2), the inverse of Bendat & Piersol's
// sigma^2 = (1 - coh) |H|^2 / (n coh).
double coherence_from_sigma(std::complex<double> h, double sigma, double averages);

// Collects lines into the FrfData and the dropped lines into warnings.
class FrfAssembler {
 public:
  FrfAssembler(const ChannelPlan& plan, bool with_sigma, bool with_coherence);
  // sigma, coh: n_out x n_in, ignored when not collected.
  void add(double freq_hz, const Eigen::MatrixXcd& h, const Eigen::MatrixXd& sigma,
           const Eigen::MatrixXd& coh);
  void drop(double freq_hz, const std::string& reason);
  void note_rcond(double freq_hz, double rcond, double warn_rcond);
  // Throws InputError if no line is left.
  FrfData finish(std::vector<std::string>& warnings, long& dropped, const std::string& what);

 private:
  FrfData frf_;
  int n_out_, n_in_;
  bool with_sigma_, with_coh_;
  std::vector<std::pair<std::string, std::vector<double>>> dropped_;  // reason, lines
  std::vector<double> poorly_conditioned_hz_;
  double worst_rcond_ = 1.0;
};

// "3 lines (5, 6, 7 Hz)" for warnings; lists at most a few frequencies.
std::string describe_lines(const std::vector<double>& freq_hz);
std::string format_number(double v);

// Median of the line powers above `fraction` of the strongest: the reference
// level for "weak line" tests. 0 when no line is excited.
double median_excited_power(const std::vector<double>& power, double fraction);

}  // namespace ambdiag::frf_estimation

namespace ambdiag {
// The estimators, one per excitation type (multisine_estimator.cc, ...).
FrfEstimate estimate_multisine(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                               const FrfEstimationOptions& options);
FrfEstimate estimate_stepsine(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                              const FrfEstimationOptions& options);
FrfEstimate estimate_welch(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                           const FrfEstimationOptions& options);
FrfEstimate estimate_lpm(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                         const FrfEstimationOptions& options);
FrfEstimate estimate_gated(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                           const FrfEstimationOptions& options);
// Gating and the local polynomial method need segments of one length; for
// others this is the Welch estimate with a warning naming `method`, else empty.
std::optional<FrfEstimate> welch_if_segments_differ(const RunRecording& run, const frf_estimation::ChannelPlan& plan,
                                                    const FrfEstimationOptions& options, const std::string& method);
}  // namespace ambdiag
