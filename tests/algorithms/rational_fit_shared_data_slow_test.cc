// Every shared FRF with a truth: the reference pump's five measurements, the
// faults, the explain cases (an acquisition delay, cross coupling, the
// paper's Table 3 pump with extra axial and housing modes) and ident_7mode.
// Prints the accuracy table of docs/fit.md.
#include <filesystem>

#include "truth_modes.h"

namespace ambdiag {
namespace {

TEST(RationalFitSlow, EveryTruthModeOfEverySharedFrfWithinHalfPercentAndTenPercentDamping) {
  std::vector<std::string> cases;
  for (int i = 1; i <= 5; ++i) cases.push_back("reference_pump/frf_ref_" + std::to_string(i) + ".csv");
  std::vector<std::string> dirs;
  for (const auto& d : std::filesystem::directory_iterator(testing::shared_data())) {
    const std::string name = d.path().filename().string();
    if ((name.rfind("fault_", 0) == 0 || name.rfind("explain_", 0) == 0) && std::filesystem::exists(d.path() / "truth.json"))
      dirs.push_back(name);
  }
  std::sort(dirs.begin(), dirs.end());
  ASSERT_GE(dirs.size(), 7u);
  std::printf("| file | mode | f truth (Hz) | zeta truth | f err (%%) | zeta err (%%) | |\n| --- | --- | --- | --- | --- | --- | --- |\n");
  for (int i = 1; i <= 5; ++i) truth_modes::expect_truth_modes_identified(cases[static_cast<size_t>(i - 1)], "reference_pump/truth.json");
  for (const auto& d : dirs) truth_modes::expect_truth_modes_identified(d + "/frf.csv", d + "/truth.json");
  truth_modes::expect_truth_modes_identified("ident_7mode/frf.csv", "ident_7mode/truth.json");
}

}  // namespace
}  // namespace ambdiag
