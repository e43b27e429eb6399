#include "test_support.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

namespace ambdiag::testing {

std::filesystem::path shared_data() {
  if (const char* env = std::getenv("AMBDIAG_SHARED_DATA"); env && *env) return env;
  return AMBDIAG_DEFAULT_SHARED_DATA;
}

std::filesystem::path data_file(const std::string& relative) {
  const auto p = shared_data() / relative;
  if (!std::filesystem::exists(p)) {
    ADD_FAILURE() << "shared test data missing: " << p;
  }
  return p;
}

std::filesystem::path scratch_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "scratch";
  const auto dir = std::filesystem::temp_directory_path() / "ambdiag-tests" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::filesystem::path write_scratch(const std::string& name, const std::string& text) {
  const auto dir = std::filesystem::temp_directory_path() / "ambdiag-tests" / "files";
  std::filesystem::create_directories(dir);
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string prefix = info ? std::string(info->test_suite_name()) + "." + info->name() + "." : "";
  const auto p = dir / (prefix + name);
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

}  // namespace ambdiag::testing
