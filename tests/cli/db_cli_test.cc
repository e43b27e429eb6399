// `ambdiag db import|export|list` on the real binary: a recording goes into
// the historian and comes out bit-identical.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "ambdiag/core/io_util.h"
#include "pg_cluster.h"
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

TEST(CliDb, RetentionSweepsOncePrintsWhatItDroppedAndADryRunChangesNothing) {
  const fs::path dir = testing::scratch_dir();
  const std::string db = "--db " + (dir / "h.db").string();
  std::string out;
  ASSERT_EQ(ambdiag_cli(dir, "db import " + testing::data_file("reference_pump/run_ref_1").string() + " " + db + " --json", &out), 0);
  const std::string run_id = nlohmann::json::parse(out)["run_id"];
  // The built-in defaults keep a run received now.
  ASSERT_EQ(ambdiag_cli(dir, "db retention " + db + " --json", &out), 0);
  EXPECT_EQ(nlohmann::json::parse(out)["samples"]["runs"], 0);
  write_file_atomic((dir / "now.json").string(), R"({"samples_days": 0})");
  const std::string policy = " --retention " + (dir / "now.json").string();
  ASSERT_EQ(ambdiag_cli(dir, "db retention " + db + policy + " --dry-run --json", &out), 0);
  auto j = nlohmann::json::parse(out);
  EXPECT_TRUE(j["dry_run"].get<bool>());
  ASSERT_EQ(j["runs"].size(), 1u);
  EXPECT_EQ(j["runs"][0]["run_id"], run_id);
  EXPECT_EQ(j["runs"][0]["reason"], "age");
  EXPECT_EQ(ambdiag_cli(dir, "db export '" + run_id + "' " + db + " -o " + (dir / "a").string()), 0) << "the dry run changed nothing";
  ASSERT_EQ(ambdiag_cli(dir, "db retention " + db + policy, &out), 0);
  EXPECT_NE(out.find("dropped the samples of 1 runs (6.6 MB)"), std::string::npos) << out;
  EXPECT_NE(out.find(run_id), std::string::npos) << out;
  EXPECT_EQ(ambdiag_cli(dir, "db export '" + run_id + "' " + db + " -o " + (dir / "b").string()), 3);
  EXPECT_NE(read_file_bytes((dir / "stderr.txt").string()).find("dropped by retention"), std::string::npos);
  ASSERT_EQ(ambdiag_cli(dir, "db list " + db + " --json", &out), 0);
  EXPECT_EQ(nlohmann::json::parse(out)["pumps"][0]["runs"][0]["samples"], "dropped") << "still listed";
  // A bad policy file names the key.
  write_file_atomic((dir / "bad.json").string(), R"({"frf_days": "long"})");
  EXPECT_EQ(ambdiag_cli(dir, "db retention " + db + " --retention " + (dir / "bad.json").string()), 3);
  EXPECT_NE(read_file_bytes((dir / "stderr.txt").string()).find("frf_days"), std::string::npos);
  EXPECT_EQ(ambdiag_cli(dir, "db retention " + db + " --dry-run --bogus"), 2);
}

// The same sweep on a PostgreSQL database (a schema of the test cluster),
// as an operator runs it beside the servers.
TEST(CliDb, RetentionSweepsAPostgreSQLDatabase) {
  const auto location = testing::postgres_test_location();
  if (!location) GTEST_SKIP() << "AMBDIAG_NO_POSTGRES=1: the PostgreSQL backend is not tested";
  const fs::path dir = testing::scratch_dir();
  const std::string db = "--db '" + *location + "'";
  std::string out;
  ASSERT_EQ(ambdiag_cli(dir, "db import " + testing::data_file("reference_pump/run_ref_1").string() + " " + db + " --json", &out), 0);
  const std::string run_id = nlohmann::json::parse(out)["run_id"];
  write_file_atomic((dir / "now.json").string(), R"({"samples_days": 0})");
  const std::string policy = " --retention " + (dir / "now.json").string();
  ASSERT_EQ(ambdiag_cli(dir, "db retention " + db + policy + " --json", &out), 0) << read_file_bytes((dir / "stderr.txt").string());
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["samples"]["runs"], 1);
  EXPECT_GT(j["samples"]["bytes"].get<std::int64_t>(), 6'000'000);
  EXPECT_EQ(j["partitions"], 0) << "today's partition is not over: the run goes row by row";
  EXPECT_EQ(ambdiag_cli(dir, "db export '" + run_id + "' " + db + " -o " + (dir / "b").string()), 3);
  EXPECT_NE(read_file_bytes((dir / "stderr.txt").string()).find("dropped by retention"), std::string::npos);
  ASSERT_EQ(ambdiag_cli(dir, "db retention " + db + policy + " --json", &out), 0);
  EXPECT_EQ(nlohmann::json::parse(out)["samples"]["runs"], 0) << "idempotent";
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
