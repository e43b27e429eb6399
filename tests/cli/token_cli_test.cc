// `ambdiag token add|list|revoke` on the real binary, also while a server's
// connection holds the same historian open and busy.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "ambdiag/storage/historian.h"
#include "cli_run.h"
#include "test_support.h"

namespace ambdiag {
namespace {

using testing::run_cli;

TEST(CliToken, AddPrintsTheTokenOnceListNeverShowsItRevokeEndsIt) {
  const auto db = (testing::scratch_dir() / "h.db").string();  // created by the first command
  const auto add = run_cli("token add --db " + db + " --role engineer --name alice --json");
  ASSERT_EQ(add.code, 0) << add.err;
  const auto j = nlohmann::json::parse(add.out);
  EXPECT_EQ(j["name"], "alice");
  EXPECT_EQ(j["role"], "engineer");
  const std::string token = j["token"];
  EXPECT_EQ(token.substr(0, 4), "amb_");

  const auto plain = run_cli("token add --db " + db + " --role viewer --name dash");
  ASSERT_EQ(plain.code, 0) << plain.err;
  const std::string dash_token = plain.out.substr(0, plain.out.find('\n'));
  EXPECT_EQ(plain.out, dash_token + "\n");  // stdout: the token alone
  EXPECT_NE(plain.err.find("shown this once"), std::string::npos) << plain.err;

  {
    auto h = storage::Historian::open(db, storage::Historian::Mode::read);
    EXPECT_EQ(h.find_token(token)->role, storage::Role::engineer);
    EXPECT_EQ(h.find_token(dash_token)->name, "dash");
  }

  const auto list = run_cli("token list --db " + db + " --json");
  ASSERT_EQ(list.code, 0) << list.err;
  const auto l = nlohmann::json::parse(list.out)["tokens"];
  ASSERT_EQ(l.size(), 2u);
  EXPECT_EQ(l[0]["name"], "alice");
  EXPECT_EQ(l[0]["role"], "engineer");
  EXPECT_TRUE(l[0].contains("created_at"));
  EXPECT_FALSE(l[0].contains("revoked_at"));
  EXPECT_FALSE(l[0].contains("token"));
  EXPECT_EQ(list.out.find(token.substr(4)), std::string::npos);
  const auto text = run_cli("token list --db " + db);
  EXPECT_EQ(text.code, 0);
  EXPECT_NE(text.out.find("alice"), std::string::npos);
  EXPECT_EQ(text.out.find(token.substr(4)), std::string::npos);

  const auto revoke = run_cli("token revoke --db " + db + " alice");
  EXPECT_EQ(revoke.code, 0) << revoke.err;
  {
    auto h = storage::Historian::open(db, storage::Historian::Mode::read);
    EXPECT_FALSE(h.find_token(token));
    EXPECT_TRUE(h.find_token(dash_token));
  }
  const auto again = run_cli("token revoke --db " + db + " alice");
  EXPECT_EQ(again.code, 3);
  EXPECT_NE(again.err.find("no active token named 'alice'"), std::string::npos) << again.err;
  const auto after = nlohmann::json::parse(run_cli("token list --db " + db + " --json").out)["tokens"];
  EXPECT_TRUE(after[0].contains("revoked_at"));
}

TEST(CliToken, UsageErrorsExitTwoAndBadNamesThree) {
  const auto db = (testing::scratch_dir() / "h.db").string();
  EXPECT_EQ(run_cli("token add --role admin --name a").code, 2);                      // no --db
  EXPECT_EQ(run_cli("token add --db " + db + " --name a").code, 2);                   // no --role
  EXPECT_EQ(run_cli("token add --db " + db + " --role root --name a").code, 2);       // no such role
  EXPECT_EQ(run_cli("token add --db " + db + " --role admin").code, 2);               // no --name
  EXPECT_EQ(run_cli("token add --db " + db + " --role admin --name a extra").code, 2);
  EXPECT_EQ(run_cli("token revoke --db " + db).code, 2);                              // no NAME
  EXPECT_EQ(run_cli("token list").code, 2);
  EXPECT_EQ(run_cli("token add --db " + db + " --role admin --name 'a b'").code, 3);
  ASSERT_EQ(run_cli("token add --db " + db + " --role admin --name a").code, 0);
  const auto taken = run_cli("token add --db " + db + " --role viewer --name a");
  EXPECT_EQ(taken.code, 3);
  EXPECT_NE(taken.err.find("'a' is taken"), std::string::npos) << taken.err;
  EXPECT_EQ(run_cli("token revoke --db " + db + " nobody").code, 3);
}

TEST(CliToken, WorksWhileAServerHoldsTheHistorianBusy) {
  const auto db = (testing::scratch_dir() / "h.db").string();
  auto server = storage::Historian::open(db);
  std::string token;
  {
    // The server's ingest holds the write lock for a while; the command waits
    // (busy timeout) and then adds its token.
    auto batch = server.write_batch();
    server.enqueue_job({"analysis", "P-1", "P-1/r1", 1, 0});
    std::atomic<bool> done{false};
    std::thread cli([&] {
      const auto r = run_cli("token add --db " + db + " --role admin --name ops --json");
      EXPECT_EQ(r.code, 0) << r.err;
      if (r.code == 0) token = nlohmann::json::parse(r.out)["token"];
      done = true;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    EXPECT_FALSE(done);  // waiting for the lock
    batch.commit();
    cli.join();
  }
  ASSERT_FALSE(token.empty());
  // The server's own connection sees it on its next request.
  EXPECT_EQ(server.find_token(token)->name, "ops");
  EXPECT_EQ(server.count_jobs(storage::JobStatus::queued), 1);
  EXPECT_EQ(run_cli("token revoke --db " + db + " ops").code, 0);
  EXPECT_FALSE(server.find_token(token));
}

}  // namespace
}  // namespace ambdiag
