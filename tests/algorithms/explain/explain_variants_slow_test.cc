// Issue 18 on unseen cases: the variations of the concealed cases
// (concealed_case_variant in concealed_cases.h: place and size of the
// concealed effect drawn from documented ranges, three machines), seeds 1
// and 2 per machine and effect, each judged by concealed_verdict (the rule
// of explain_concealed_slow_test.cc, expectations from the drawn truth).
// bench_explain_concealed --variants N runs more seeds and prints a table;
// docs/explain.md, "Concealed cases (issue 18)", "Variations", records it.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <tuple>

#include "concealed_cases.h"

namespace ambdiag {
namespace {

class ExplainConcealedVariant : public ::testing::TestWithParam<std::tuple<std::string, std::string, unsigned>> {};

TEST_P(ExplainConcealedVariant, NamesTheConcealedPhysicsAloneOrSaysUnexplained) {
  const auto& [machine, effect, seed] = GetParam();
  const testing::ConcealedCase c = testing::concealed_case_variant(testing::reference_pump_model(), machine, effect, seed);
  std::printf("%s: %s (%d draws discarded)\n", c.name.c_str(), c.drawn.c_str(), c.discarded);
  ExplainOptions opt;
  if (std::getenv("AMBDIAG_EXPLAIN_TRACE"))  // the selection steps, for a failing draw
    opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  const ExplainResult r = explain(c.nominal, c.measured, opt);
  for (const auto& f : testing::concealed_verdict(c, r)) ADD_FAILURE() << c.name << " (" << c.drawn << "): " << f;
}

INSTANTIATE_TEST_SUITE_P(Issue18Variants, ExplainConcealedVariant,
                         ::testing::Combine(::testing::ValuesIn(testing::concealed_variant_machines()),
                                            ::testing::ValuesIn(testing::concealed_effects()), ::testing::Values(1u, 2u)),
                         [](const ::testing::TestParamInfo<ExplainConcealedVariant::ParamType>& param_info) {
                           return std::get<0>(param_info.param) + "_" + std::get<1>(param_info.param) + "_seed" +
                                  std::to_string(std::get<2>(param_info.param));
                         });

}  // namespace
}  // namespace ambdiag
