#include "klu_complex.h"

#include <klu.h>

#include <stdexcept>
#include <string>

namespace ambdiag::detail {

namespace {

// Refactorization reuses the first pivot order; if the reciprocal pivot
// ratio drops by this factor, pivots are chosen again.
constexpr double kRcondDrop = 1e-6;

double* as_doubles(const std::complex<double>* p) {
  // std::complex<double> is laid out as two doubles (re, im), which is KLU's
  // packed complex format.
  return reinterpret_cast<double*>(const_cast<std::complex<double>*>(p));
}

}  // namespace

struct KluComplex::State {
  klu_common common{};
  klu_symbolic* symbolic = nullptr;
  klu_numeric* numeric = nullptr;
  double rcond_at_factor = 0.0;
  int n = 0;

  ~State() {
    if (numeric) klu_z_free_numeric(&numeric, &common);
    if (symbolic) klu_free_symbolic(&symbolic, &common);
  }
  void check(const char* what) const {
    if (common.status < KLU_OK) throw std::runtime_error(std::string("KLU ") + what + " failed, status " +
                                                         std::to_string(common.status));
  }
};

KluComplex::KluComplex(const Matrix& pattern) : state_(std::make_unique<State>()) {
  if (!pattern.isCompressed()) throw std::logic_error("KluComplex: pattern must be compressed");
  klu_defaults(&state_->common);
  state_->n = static_cast<int>(pattern.rows());
  state_->symbolic = klu_analyze(state_->n, const_cast<int*>(pattern.outerIndexPtr()),
                                 const_cast<int*>(pattern.innerIndexPtr()), &state_->common);
  if (!state_->symbolic) state_->check("analyze");
}

KluComplex::~KluComplex() = default;
KluComplex::KluComplex(KluComplex&&) noexcept = default;
KluComplex& KluComplex::operator=(KluComplex&&) noexcept = default;

bool KluComplex::factorize(const Matrix& a) {
  State& s = *state_;
  int* ap = const_cast<int*>(a.outerIndexPtr());
  int* ai = const_cast<int*>(a.innerIndexPtr());
  double* ax = as_doubles(a.valuePtr());
  if (s.numeric) {
    if (klu_z_refactor(ap, ai, ax, s.symbolic, s.numeric, &s.common) && klu_z_rcond(s.symbolic, s.numeric, &s.common) &&
        s.common.rcond > kRcondDrop * s.rcond_at_factor) {
      return true;
    }
    klu_z_free_numeric(&s.numeric, &s.common);
  }
  s.numeric = klu_z_factor(ap, ai, ax, s.symbolic, &s.common);
  if (!s.numeric) {
    if (s.common.status == KLU_SINGULAR) return false;
    s.check("factor");
  }
  if (!klu_z_rcond(s.symbolic, s.numeric, &s.common)) s.check("rcond");
  s.rcond_at_factor = s.common.rcond;
  return s.common.rcond > 0.0;
}

void KluComplex::solve_in_place(Eigen::MatrixXcd& b) const {
  State& s = *state_;
  if (!s.numeric) throw std::logic_error("KluComplex: solve before factorize");
  if (b.cols() == 0) return;
  if (!klu_z_solve(s.symbolic, s.numeric, static_cast<int>(b.rows()), static_cast<int>(b.cols()), as_doubles(b.data()),
                   &s.common)) {
    s.check("solve");
  }
}

struct KluReal::State {
  klu_common common{};
  klu_symbolic* symbolic = nullptr;
  klu_numeric* numeric = nullptr;
  double rcond = 0.0;

  ~State() {
    if (numeric) klu_free_numeric(&numeric, &common);
    if (symbolic) klu_free_symbolic(&symbolic, &common);
  }
  void check(const char* what) const {
    if (common.status < KLU_OK) throw std::runtime_error(std::string("KLU ") + what + " failed, status " +
                                                         std::to_string(common.status));
  }
};

KluReal::KluReal(const Matrix& a) : state_(std::make_unique<State>()) {
  if (!a.isCompressed()) throw std::logic_error("KluReal: matrix must be compressed");
  State& s = *state_;
  klu_defaults(&s.common);
  const int n = static_cast<int>(a.rows());
  int* ap = const_cast<int*>(a.outerIndexPtr());
  int* ai = const_cast<int*>(a.innerIndexPtr());
  s.symbolic = klu_analyze(n, ap, ai, &s.common);
  if (!s.symbolic) s.check("analyze");
  s.numeric = klu_factor(ap, ai, const_cast<double*>(a.valuePtr()), s.symbolic, &s.common);
  if (!s.numeric) {
    if (s.common.status == KLU_SINGULAR) return;
    s.check("factor");
  }
  if (!klu_rcond(s.symbolic, s.numeric, &s.common)) s.check("rcond");
  s.rcond = s.common.rcond;
}

KluReal::~KluReal() = default;
KluReal::KluReal(KluReal&&) noexcept = default;
KluReal& KluReal::operator=(KluReal&&) noexcept = default;

double KluReal::rcond() const { return state_->numeric ? state_->rcond : 0.0; }

void KluReal::solve_in_place(Eigen::MatrixXd& b) const {
  State& s = *state_;
  if (!s.numeric) throw std::logic_error("KluReal: solve with a singular matrix");
  if (b.cols() == 0) return;
  if (!klu_solve(s.symbolic, s.numeric, static_cast<int>(b.rows()), static_cast<int>(b.cols()), b.data(), &s.common)) {
    s.check("solve");
  }
}

}  // namespace ambdiag::detail
