// Issue 18's target on the concealed cases (concealed_cases.h): on two
// machines, explain names the one concealed physics at its place with its
// parameters (tolerances in concealed_verdict), claims nothing else, fits
// to the noise floor, says "unexplained" (with the band) for the absorber
// that the catalogue cannot express. Time (under 10 s CPU per case) is
// measured by bench/bench_explain_concealed, not here. One case runs in the
// fast suite (concealed_cases_test.cc); docs/explain.md, "Concealed cases
// (issue 18)", records which cases meet the target.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <tuple>

#include "concealed_cases.h"

namespace ambdiag {
namespace {

void expect_target(const std::string& machine, const std::string& effect) {
  const testing::ConcealedCase c = testing::concealed_case(testing::reference_pump_model(), machine, effect);
  ExplainOptions opt;
  if (std::getenv("AMBDIAG_EXPLAIN_TRACE"))  // the selection steps, for a failing case
    opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  const ExplainResult r = explain(c.nominal, c.measured, opt);
  for (const auto& f : testing::concealed_verdict(c, r)) ADD_FAILURE() << c.name << ": " << f;
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

}  // namespace
}  // namespace ambdiag
