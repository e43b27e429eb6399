// `ambdiag db import|export|list` on the real binary: a recording goes into
// the historian and comes out bit-identical.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "ambdiag/core/io_util.h"
#include "test_support.h"

namespace ambdiag {
namespace {

namespace fs = std::filesystem;

// Exit code of `ambdiag ARGS`, stdout left in `out`.
int ambdiag_cli(const fs::path& dir, const std::string& args, std::string* out = nullptr) {
  const fs::path out_file = dir / "stdout.txt";
  const std::string cmd = std::string(AMBDIAG_CLI) + " " + args + " >" + out_file.string() + " 2>" + (dir / "stderr.txt").string();
  const int status = std::system(cmd.c_str());
  if (out) *out = read_file_bytes(out_file.string());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CliDb, ImportThenExportGivesTheRecordingBackBitIdentical) {
  const fs::path dir = testing::scratch_dir();
  const fs::path run = testing::data_file("reference_pump/run_ref_1");
  const std::string db = "--db " + (dir / "h.db").string();
  std::string out;
  ASSERT_EQ(ambdiag_cli(dir, "db import " + run.string() + " " + db + " --json", &out), 0);
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["status"], "complete");
  EXPECT_EQ(j["duplicates"], 0);
  const std::string run_id = j["run_id"];

  ASSERT_EQ(ambdiag_cli(dir, "db import " + run.string() + " " + db + " --json", &out), 0);  // again: no-op
  EXPECT_EQ(nlohmann::json::parse(out)["duplicates"], j["chunks"]);

  ASSERT_EQ(ambdiag_cli(dir, "db export '" + run_id + "' " + db + " -o " + (dir / "back").string()), 0);
  for (const char* f : {"run.json", "samples.f32"})
    EXPECT_EQ(read_file_bytes((dir / "back" / f).string()), read_file_bytes((run / f).string())) << f;

  ASSERT_EQ(ambdiag_cli(dir, "db list " + db + " --json", &out), 0);
  const auto list = nlohmann::json::parse(out);
  ASSERT_EQ(list["pumps"].size(), 1u);
  EXPECT_EQ(list["pumps"][0]["runs"][0]["run_id"], run_id);
}

TEST(CliDb, BadInputExitsThreeAndUsageErrorsTwo) {
  const fs::path dir = testing::scratch_dir();
  const std::string db = "--db " + (dir / "h.db").string();
  EXPECT_EQ(ambdiag_cli(dir, "db import " + (dir / "nope").string() + " " + db), 3);
  EXPECT_EQ(ambdiag_cli(dir, "db export no/such:run " + db + " -o " + (dir / "x").string()), 3);
  EXPECT_FALSE(fs::exists(dir / "x"));
  write_file_atomic((dir / "garbage.db").string(), std::string(5000, 'g'));
  EXPECT_EQ(ambdiag_cli(dir, "db list --db " + (dir / "garbage.db").string()), 3);
  EXPECT_EQ(ambdiag_cli(dir, "db import " + (dir / "nope").string()), 2);  // no --db
  EXPECT_EQ(ambdiag_cli(dir, "db export RUN " + db), 2);                  // no -o
}

}  // namespace
}  // namespace ambdiag
