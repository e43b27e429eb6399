// Helpers shared by the tests: where the shared data lives, scratch folders.
#pragma once

#include <filesystem>
#include <string>

namespace ambdiag::testing {

// ../shared/data (overridable with AMBDIAG_SHARED_DATA).
std::filesystem::path shared_data();
// Path of a file under shared data; the test is skipped with a message if
// the shared data is not present (it always is in CI).
std::filesystem::path data_file(const std::string& relative);
// A fresh, empty scratch folder unique to the running test.
std::filesystem::path scratch_dir();
// Writes text to a file in the scratch folder and returns its path.
std::filesystem::path write_scratch(const std::string& name, const std::string& text);

}  // namespace ambdiag::testing
