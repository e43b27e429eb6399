// Issue 18's target on the concealed cases (concealed_cases.h): on two
// machines, explain names the one concealed physics at its place with its
// parameters (tolerances in concealed_verdict), claims nothing else, fits
// to the noise floor, says "unexplained" (with the band) for the absorber
// that the catalogue cannot express, and takes under 10 s CPU per case.
// Slow-labelled while explain does not meet it (docs/explain.md,
// "Concealed cases (issue 18)", records which cases fail and how).
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <tuple>

#include "concealed_cases.h"

namespace ambdiag {
namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void expect_target(const std::string& machine, const std::string& effect) {
  const testing::ConcealedCase c = testing::concealed_case(testing::reference_pump_model(), machine, effect);
  ExplainOptions opt;
  if (std::getenv("AMBDIAG_EXPLAIN_TRACE"))  // the selection steps, for a failing case
    opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  const double t0 = cpu_seconds();
  const ExplainResult r = explain(c.nominal, c.measured, opt);
  const double cpu = cpu_seconds() - t0;
  for (const auto& f : testing::concealed_verdict(c, r)) ADD_FAILURE() << c.name << ": " << f;
  EXPECT_LT(cpu, 10.0) << c.name << ": explain took " << cpu << " s CPU";
}

class ExplainConcealedCase : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(ExplainConcealedCase, NamesTheConcealedPhysicsAloneOrSaysUnexplained) {
  expect_target(std::get<0>(GetParam()), std::get<1>(GetParam()));
}

INSTANTIATE_TEST_SUITE_P(Issue18, ExplainConcealedCase,
                         ::testing::Combine(::testing::ValuesIn(testing::concealed_machines()),
                                            ::testing::ValuesIn(testing::concealed_effects())),
                         [](const ::testing::TestParamInfo<ExplainConcealedCase::ParamType>& param_info) {
                           return std::get<0>(param_info.param) + "_" + std::get<1>(param_info.param);
                         });

// The quick one of the set, to move to the fast tests when it passes.
TEST(ExplainConcealedQuick, GyroscopicOmittedOnTheReferencePump) { expect_target("reference_pump", "gyroscopic_omitted"); }

}  // namespace
}  // namespace ambdiag
