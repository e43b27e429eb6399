// Issue 18 on unseen cases: the variations of the concealed cases
// (concealed_case_variant in concealed_cases.h: place and size of the
// concealed effect drawn from documented ranges, three machines), seeds 1
// and 2 per machine and effect, each judged by concealed_verdict (the rule
// of explain_concealed_slow_test.cc, expectations from the drawn truth).
// bench_explain_concealed --variants N runs more seeds and prints a table;
// docs/explain.md, "Concealed cases (issue 18)", "Variations", records it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <tuple>

#include "concealed_cases.h"

namespace ambdiag {
namespace {

// Draws that fail the target on the code this test was added with (commit
// message and docs/explain.md, "Variations", say what explain named and
// why). They still fail here (the verdict is not weakened); the prefix
// says the failure is known, so a new failure stands out. Remove a draw
// from the list when explain meets the target on it.
const char* const kKnownFailingDraws[] = {
    // Omitted coupling at 0.57 / 0.71 / 0.63 x its design stiffness: a
    // support at node 1 or 2 (next to the truth's node 0) with a second
    // support at node 19, seal and housing terms and updates; not at node 0.
    "reference_pump/coupling_omitted#2",
    "second_pump/coupling_omitted#1",
    "second_pump/coupling_omitted#2",
    // Absorber tuned 584 Hz at node 9 (3.7 % of the rotor): claimed as an
    // added mass at its node plus an acquisition delay and updates.
    "reference_pump/absorber#2",
    // Absorber tuned 808 Hz at node 8 (2.7 %, excess 35 over a plain
    // mass): added masses at nodes 4 and 12, housing modes, updates.
    "second_pump/absorber#2",
};

bool known_failing(const std::string& name) {
  return std::find(std::begin(kKnownFailingDraws), std::end(kKnownFailingDraws), name) != std::end(kKnownFailingDraws);
}

class ExplainConcealedVariant : public ::testing::TestWithParam<std::tuple<std::string, std::string, unsigned>> {};

TEST_P(ExplainConcealedVariant, NamesTheConcealedPhysicsAloneOrSaysUnexplained) {
  const auto& [machine, effect, seed] = GetParam();
  const testing::ConcealedCase c = testing::concealed_case_variant(testing::reference_pump_model(), machine, effect, seed);
  std::printf("%s: %s (%d draws discarded)\n", c.name.c_str(), c.drawn.c_str(), c.discarded);
  ExplainOptions opt;
  if (std::getenv("AMBDIAG_EXPLAIN_TRACE"))  // the selection steps, for a failing draw
    opt.progress = [](const std::string& s) { std::fprintf(stderr, "explain: %s\n", s.c_str()); };
  const ExplainResult r = explain(c.nominal, c.measured, opt);
  const std::string known = known_failing(c.name) ? "[known failing draw, see kKnownFailingDraws] " : "";
  for (const auto& f : testing::concealed_verdict(c, r)) ADD_FAILURE() << known << c.name << " (" << c.drawn << "): " << f;
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
