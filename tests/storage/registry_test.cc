// The pumps' plant models and references (schema v4), and the migration of
// a v3 file to v4.
#include <gtest/gtest.h>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

using ambdiag::testing::as_string;
using ambdiag::testing::checksum_of;
using ambdiag::testing::cut_chunks;
using ambdiag::testing::identification_json_text;
using ambdiag::testing::run_json_text;
using ambdiag::testing::samples_bytes;

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class HistorianModelsTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianModelsTest);
class HistorianReferencesTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianReferencesTest);

// Stores a run from its run.json text: complete (all chunks and the right
// end), incomplete (a wrong checksum) or still receiving (no end).
void store_run(Historian& h, const std::string& run_json, RunStatus status) {
  const auto header = run_header_from_json(run_json);
  const int n = static_cast<int>(header.channels.size());
  const auto bytes = samples_bytes(300, n, 3);
  h.begin_run(header);
  h.put_chunks(header.run_id, cut_chunks(bytes, n, 100));
  if (status == RunStatus::receiving) return;
  const auto end = h.end_run(header.run_id, 300, checksum_of(bytes) + (status == RunStatus::incomplete ? 1 : 0));
  ASSERT_EQ(end.status, status) << end.reason;
}

TEST_P(HistorianModelsTest, EachPutIsANewVersionOfItsPumpAndEveryVersionIsKept) {
  auto h = Historian::open(location());
  EXPECT_FALSE(h.find_model("P-1"));
  EXPECT_TRUE(h.list_models("P-1").empty());
  EXPECT_EQ(h.put_model("P-1", R"({"a": 1})", "alice", "first"), 1);
  EXPECT_EQ(h.put_model("P-2", R"({"b": 1})", ""), 1);  // versions count per pump
  EXPECT_EQ(h.put_model("P-1", R"({"a":   2})", "bob", "adopted from explain job 17"), 2);

  const auto latest = h.find_model("P-1");
  ASSERT_TRUE(latest);
  EXPECT_EQ(latest->version, 2);
  EXPECT_EQ(latest->plant_json, R"({"a":   2})");  // byte for byte
  EXPECT_EQ(latest->created_by, "bob");
  EXPECT_EQ(latest->comment, "adopted from explain job 17");
  EXPECT_FALSE(latest->created_at.empty());
  const auto first = h.find_model("P-1", 1);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->plant_json, R"({"a": 1})");
  EXPECT_EQ(first->created_by, "alice");
  EXPECT_FALSE(h.find_model("P-1", 3));
  EXPECT_FALSE(h.find_model("P-3"));

  const auto list = h.list_models("P-1");
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].version, 1);
  EXPECT_EQ(list[1].version, 2);
  EXPECT_EQ(list[1].comment, "adopted from explain job 17");
  EXPECT_TRUE(list[0].plant_json.empty());  // lists leave the plant out

  // The pump exists before any run of it.
  const auto pump = h.find_pump("P-2");
  ASSERT_TRUE(pump);
  EXPECT_EQ(pump->n_runs, 0);
}

TEST_P(HistorianModelsTest, AReaderSeesTheVersionsAndAnEmptyPumpOrPlantIsRefused) {
  const auto path = location();
  auto h = Historian::open(path);
  h.put_model("P-1", "{}", "");
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(r.find_model("P-1")->version, 1);
  EXPECT_THROW(r.put_model("P-1", "{}", ""), std::logic_error);
  EXPECT_THROW(h.put_model("", "{}", ""), InputError);
  EXPECT_THROW(h.put_model("P-1", "", ""), InputError);
  EXPECT_EQ(h.list_models("P-1").size(), 1u);
}

TEST_P(HistorianReferencesTest, OnlyCompleteIdentificationRunsOfThePumpEachOnce) {
  auto h = Historian::open(location());
  store_run(h, identification_json_text("P-1/a", "P-1"), RunStatus::complete);
  store_run(h, identification_json_text("P-1/b", "P-1"), RunStatus::complete);
  store_run(h, identification_json_text("P-1/recv", "P-1"), RunStatus::receiving);
  store_run(h, identification_json_text("P-1/bad", "P-1"), RunStatus::incomplete);
  store_run(h, run_json_text("P-1/mon", 2, "P-1"), RunStatus::complete);
  store_run(h, identification_json_text("P-2/a", "P-2"), RunStatus::complete);

  const auto refused = [&](std::vector<std::string> runs) {
    return input_error_of([&] { h.put_reference("P-1", runs, "alice"); });
  };
  EXPECT_EQ(refused({}), "put_reference 'P-1': no runs (a reference needs at least one)");
  EXPECT_EQ(refused({"P-1/a", "P-1/nope"}), "put_reference 'P-1': run 'P-1/nope': unknown run");
  EXPECT_EQ(refused({"P-1/a", "P-2/a"}), "put_reference 'P-1': run 'P-2/a' is of pump 'P-2'");
  EXPECT_EQ(refused({"P-1/recv"}), "put_reference 'P-1': run 'P-1/recv' is receiving, not complete");
  EXPECT_NE(refused({"P-1/bad"}).find("run 'P-1/bad' is incomplete (checksum mismatch"), std::string::npos)
      << refused({"P-1/bad"});
  EXPECT_EQ(refused({"P-1/mon"}), "put_reference 'P-1': run 'P-1/mon' is a monitoring run, not an identification run");
  EXPECT_EQ(refused({"P-1/a", "P-1/b", "P-1/a"}), "put_reference 'P-1': run 'P-1/a' is listed twice");
  EXPECT_FALSE(h.find_reference("P-1"));  // nothing of a refused call is stored

  EXPECT_EQ(h.put_reference("P-1", {"P-1/b", "P-1/a"}, "alice"), 1);
  EXPECT_EQ(h.put_reference("P-1", {"P-1/a"}, "bob"), 2);
  EXPECT_EQ(h.put_reference("P-2", {"P-2/a"}, ""), 1);
  const auto latest = h.find_reference("P-1");
  ASSERT_TRUE(latest);
  EXPECT_EQ(latest->version, 2);
  EXPECT_EQ(latest->run_ids, std::vector<std::string>{"P-1/a"});
  EXPECT_EQ(latest->created_by, "bob");
  const auto first = h.find_reference("P-1", 1);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->run_ids, (std::vector<std::string>{"P-1/b", "P-1/a"}));  // in the order given
  EXPECT_FALSE(h.find_reference("P-1", 3));
  EXPECT_FALSE(h.find_reference("P-3"));
}

TEST(HistorianSchema, AVersion3FileIsMigratedToVersion4KeepingItsRuns) {
  const auto path = db_path();
  const auto a = samples_bytes(300, 2, 7);
  {
    auto h = Historian::open(path);
    h.begin_run(run_header_from_json(run_json_text("P-7/old", 2)));
    h.put_chunks("P-7/old", cut_chunks(a, 2, 100));
    h.end_run("P-7/old", 300, checksum_of(a));
  }
  // Back to what migration 3 left: v1's unused jobs table, no v4 tables.
  downgrade_schema(path, 3);
  ASSERT_EQ(raw_query_int(path, "SELECT count(*) FROM sqlite_schema WHERE name = 'tokens'"), 0);
  EXPECT_THROW(Historian::open(path, Historian::Mode::read), InputError);  // readers do not migrate
  {
    auto h = Historian::open(path);
    const auto old = h.find_run("P-7/old");
    ASSERT_TRUE(old);
    EXPECT_EQ(old->status, RunStatus::complete);
    EXPECT_EQ(h.read_samples("P-7/old"), as_string(a));
    EXPECT_EQ(h.put_model("P-7", "{}", ""), 1);
    EXPECT_TRUE(h.enqueue_job({"analysis", "P-7", "P-7/old", 1, 0}).second);
    EXPECT_FALSE(h.add_token("ops", Role::admin).empty());
  }
  EXPECT_EQ(raw_query_int(path, "PRAGMA user_version"), Historian::schema_version());
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM sqlite_schema WHERE name = 'alarm_events'"), 1);
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM pragma_table_info('jobs') WHERE name = 'attempts'"), 1);
  auto r = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(r.count_jobs(JobStatus::queued), 1);
  EXPECT_EQ(r.list_runs("P-7").size(), 1u);
}

}  // namespace
}  // namespace ambdiag::storage
