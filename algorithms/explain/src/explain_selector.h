// The selection engine of explain (explain.h, step 2): a selection of
// pieces (parameter updates and physics), trials of candidates on top of
// it, the screening that ranks them cheaply, the greedy step, the refits
// and prunes that tidy a selection, and the challengers that question it
// (parsimony, alternatives, the resonant attachment). Private to the
// explain domain; explain_select.cc drives it.
//   explain_selector.cc            construction, trials, screening, the greedy step
//   explain_selector_refine.cc     refits, locations, merges, prunes
//   explain_selector_challenge.cc  parsimony, alternatives, the attachment
#pragma once

#include <complex>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ambdiag/algorithms/explain/explain.h"
#include "ambdiag/algorithms/explain/missing_physics.h"
#include "ambdiag/algorithms/model/plant_frf_fit.h"
#include "explain_screen.h"

namespace ambdiag::detail {

inline std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

struct Selected {
  Candidate c;
  std::vector<double> x;
  Explanation report;
};

inline bool on_foreign_bound(const FitParameter& p, double v) {
  return p.lower < p.upper && ((v <= p.lower && p.lower != p.initial) || (v >= p.upper && p.upper != p.initial));
}

struct Trial {
  const Candidate* c = nullptr;
  const Candidate* c2 = nullptr;  // second of a pair
  std::vector<double> x;          // params of c then c2
  double chi2_fit = 0.0, chi2_val = 0.0;
  double gain_fit = 0.0, gain_val = 0.0, threshold_fit = 0.0, threshold_val = 0.0;
  std::vector<double> sd;
  bool cheap = false;  // figures from the low-rank model (explain_screen.h), not yet from the FE model
  // A physics whose fit ends on a bound other than its neutral value wants
  // more than is plausible: it is not the explanation, whatever it gains.
  bool pinned() const {
    size_t k = 0;
    for (const Candidate* cc : {c, c2}) {
      if (!cc) continue;
      for (const auto& p : cc->params) {
        if (k >= x.size()) return false;
        if (!cc->is_update && on_foreign_bound(p, x[k])) return true;
        ++k;
      }
    }
    return false;
  }
  bool passes() const { return gain_fit > threshold_fit && gain_val > threshold_val && !pinned(); }
  double margin() const { return std::min(gain_fit - threshold_fit, gain_val - threshold_val); }
};

inline std::vector<double> neutral(const Candidate& c) {
  std::vector<double> x;
  for (const auto& p : c.params) x.push_back(p.initial);
  return x;
}

class Selector {
 public:
  Selector(const PlantModel& nominal, PlantFrfEvaluator& eval, const ExplainOptions& opt);

  PlantVariant build(const std::vector<Selected>& sel, const Candidate* extra = nullptr, const std::vector<double>* xe = nullptr,
                     const Candidate* extra2 = nullptr, size_t split = 0) const;

  // The weighted residual of a variant. A trial variant whose model fails
  // numerically (an eigenproblem that does not converge at some extreme
  // parameter value) is not an error of the run: it gets a residual so large
  // that every fit steps away from it. Bad input (InputError) still throws.
  std::vector<std::complex<double>> residual(const PlantVariant& v, const std::vector<int>& lines);

  double chi2(const PlantVariant& v, const std::vector<int>& lines) { return chi2_of(residual(v, lines)); }

  double threshold(int params, double chi2_now) const;

  // Fits candidate(s) on top of the selection, the selection held fixed.
  Trial try_candidate(const std::vector<Selected>& sel, const Candidate& c, const Candidate* c2, double cf, double cv,
                      const std::vector<double>* start = nullptr);

  // Linearised chi2 drop of a rotor candidate from finite-difference
  // Jacobian columns at its neutral point. A column depends only on the
  // rotor and the delay of the current selection (housings and the axial
  // model cancel in the difference), so it is cached by those.
  double screen(const std::vector<Selected>& sel, const Candidate& c, const std::vector<std::complex<double>>& r0, double cf,
                const std::string& state, double delay_s, std::vector<double>* start);

  // Screens a rotor candidate on the low-rank model of the current rotor
  // (explain_screen.h): linearised drop first; `fit` also fits its
  // parameters on that model (no FE solve) and gives the drop on both halves.
  struct Cheap {
    bool ok = false;
    double gain_fit = 0.0, gain_val = 0.0;
    std::vector<double> x;
  };
  Cheap cheap_screen(detail::RotorScreen& scr, const Candidate& c, const std::vector<std::complex<double>>& r0,
                     const std::vector<std::complex<double>>& rv0, double cf, double cv, bool fit,
                     const std::vector<double>* start = nullptr);

  // The low-rank screen of the current rotor. It is rebuilt when the set of
  // selected rotor changes (or the delay) changes, not when a refit moved
  // their values a little: the screen's changes are added to the exact
  // current residual, so a slightly older receptance errs to second order.
  bool has_lowrank(detail::RotorScreen& scr, const Candidate& c);

  detail::RotorScreen& screen_for(const std::vector<Selected>& sel, const PlantVariant& cur);

  Trial evaluate_fixed(const std::vector<Selected>& sel, const Candidate& c, double cf, double cv);

  // One selection step over updates and physics. An update is preferred
  // when it explains at least 80 % of what the best physics candidate does:
  // a wrong parameter is not missing physics. When no single candidate
  // pays, the best pair of the three best singles (unless `pairs` is false:
  // the challengers want one piece). Candidates whose id is in `refused`
  // are not tried (explain_select.cc: a step that would raise the NRMSE).
  std::optional<Trial> step(const std::vector<Selected>& sel, const std::vector<Candidate>& updates,
                            const std::vector<Candidate>& physics, bool pairs = true,
                            const std::set<std::string>& refused = {});

  static bool is_selected(const std::vector<Selected>& sel, const Candidate& c);

  // Refits every selected parameter together.
  void refit_all(std::vector<Selected>& sel, int max_iterations = 6);

  // An update at its bound and a physics candidate that scale the same
  // coefficients (same direction key) are one change beyond the bounds:
  // the physics with the product of the factors.
  void fold_updates(std::vector<Selected>& sel);

  // Moves discrete locations (added mass node) to a neighbour when that fits
  // both halves better with the other selections held.
  void refine_locations(std::vector<Selected>& sel);

  // Greedy steps can split one added mass over two nodes either side of it;
  // try one mass at each node between them instead (parameters: the sum).
  void merge_between(std::vector<Selected>& sel);

  // Drops selections whose removal costs less than their penalty on either
  // half, and updates whose change is within kSignificantSd standard
  // deviations (of the joint refit) of the nominal value in every parameter.
  void prune(std::vector<Selected>& sel);

  // Parsimony (issue 18): greedy steps can take a wrong first piece (an
  // update near its bound, a mass at the wrong node) and patch it with
  // more. With two or more pieces selected, the best single physics on the
  // nominal model (one selection step from there) replaces them all when
  // it fits both halves at least as well by the penalised criterion.
  // Returns the id of the one that replaced them.
  std::optional<std::string> replace_by_single(std::vector<Selected>& sel, const std::vector<Candidate>& physics);

  // Confusable physics (issue 18): for each physics claim, the best physics
  // of another kind fitted in its place (the other pieces held). Where the
  // claim does not fit decisively better on both halves (chi2 lower by more
  // than 2 ln 100: a likelihood ratio of 100), one recording cannot tell
  // the two apart and the other is reported beside it. The comparison is
  // of the fits, not penalised: which of two equal fits is the simpler one
  // parsimony has already decided by choosing the claim.
  struct Alternative {
    std::string claim_id;
    Candidate c;
    std::vector<double> x;
    double delta_fit = 0.0, delta_val = 0.0;  // chi2 of the alternative minus the claim's
  };
  std::vector<Alternative> alternatives(const std::vector<Selected>& sel, const std::vector<Candidate>& physics);

  // What the catalogue cannot express (issue 18, pattern 3): an extra mode
  // of a part attached to the rotor gets "explained" by several catalogue
  // pieces and parameter updates. The challenger is one resonant
  // attachment (f, zeta, m at a node; missing_physics.h), fitted exactly on
  // the low-rank model of the nominal rotor, at every node. When the best
  // one fits both halves at least as well as the whole selection by the
  // penalised criterion, with its frequency inside the measured band and
  // no parameter on a bound, the selection goes and the attachment is
  // returned: it locates what stays unexplained. (An attachment beside a
  // real parameter error would lose the error too; not handled.)
  struct Attachment {
    Candidate c;
    std::vector<double> x;
    double chi2_fit = 0.0, chi2_val = 0.0;
  };
  std::optional<Attachment> attachment_challenge(std::vector<Selected>& sel);

  void progress(const std::string& s) const;

  const std::vector<int>& fit_lines() const { return fit_; }
  const std::vector<int>& val_lines() const { return val_; }
  const std::vector<int>& all_lines() const { return all_; }
  int evaluations() const { return evaluations_; }

 private:
  const PlantModel& nominal_;
  PlantFrfEvaluator& eval_;
  const ExplainOptions& opt_;
  std::vector<int> fit_, val_, all_;
  double penalty_per_param_ = 0.0;
  int evaluations_ = 0;
  std::map<std::string, std::vector<std::complex<double>>> dcache_;
  std::unique_ptr<detail::RotorScreen> screen_;
  std::map<std::string, std::pair<double, std::vector<double>>> stale_gain_;  // lazy greedy bounds on this screen
  std::vector<int> screen_lines_;  // set once in the constructor; the current residual there:
  std::vector<std::complex<double>> screen_r0_;
  double screen_cf_ = 0.0;
  std::string screen_key_;
  std::map<std::string, std::pair<bool, std::optional<detail::LowRankChange>>> lowrank_;
};

}  // namespace ambdiag::detail
