// API tokens (schema v4): secrets shown once, only their SHA-256 stored.
#include <gtest/gtest.h>

#include <filesystem>

#include "ambdiag/core/error.h"
#include "ambdiag/core/io_util.h"
#include "ambdiag/core/sha256.h"
#include "ambdiag/storage/historian.h"
#include "historian_fixture.h"
#include "sqlite_raw.h"
#include "test_support.h"

namespace ambdiag::storage {
namespace {

std::string db_path() { return (ambdiag::testing::scratch_dir() / "h.db").string(); }

class HistorianTokensTest : public ambdiag::testing::BackendTest {};
AMBDIAG_ON_BOTH_BACKENDS(HistorianTokensTest);

TEST_P(HistorianTokensTest, ASecretFindsItsHolderAndRoleUntilRevoked) {
  const auto path = location();
  auto h = Historian::open(path);
  const auto secret = h.add_token("alice", Role::engineer);
  const auto other = h.add_token("ops@plant-1", Role::admin);
  EXPECT_NE(secret, other);
  ASSERT_EQ(secret.size(), 4u + 43u);
  EXPECT_EQ(secret.substr(0, 4), "amb_");
  EXPECT_EQ(secret.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_", 4),
            std::string::npos);

  const auto who = h.find_token(secret);
  ASSERT_TRUE(who);
  EXPECT_EQ(who->name, "alice");
  EXPECT_EQ(who->role, Role::engineer);
  EXPECT_FALSE(who->created_at.empty());
  EXPECT_FALSE(who->revoked_at);
  EXPECT_EQ(h.find_token(other)->role, Role::admin);

  // REST answers from read connections: they see the token too.
  auto reader = Historian::open(path, Historian::Mode::read);
  EXPECT_EQ(reader.find_token(secret)->name, "alice");
  EXPECT_THROW(reader.add_token("x", Role::viewer), std::logic_error);

  EXPECT_TRUE(h.revoke_token("alice"));
  EXPECT_FALSE(h.find_token(secret));
  EXPECT_FALSE(reader.find_token(secret));
  EXPECT_FALSE(h.revoke_token("alice"));   // no active token of that name
  EXPECT_FALSE(h.revoke_token("nobody"));
  EXPECT_TRUE(h.find_token(other));

  const auto list = h.list_tokens();
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].name, "alice");
  EXPECT_TRUE(list[0].revoked_at);
  EXPECT_EQ(list[1].name, "ops@plant-1");
  EXPECT_FALSE(list[1].revoked_at);

  // A revoked name can be given again; the old secret stays refused.
  const auto renewed = h.add_token("alice", Role::viewer);
  EXPECT_EQ(h.find_token(renewed)->role, Role::viewer);
  EXPECT_FALSE(h.find_token(secret));
  EXPECT_FALSE(h.list_tokens()[0].revoked_at);
}

TEST_P(HistorianTokensTest, AnUnknownOrAlteredSecretFindsNobody) {
  auto h = Historian::open(location());
  const auto secret = h.add_token("alice", Role::viewer);
  EXPECT_FALSE(h.find_token(""));
  EXPECT_FALSE(h.find_token("amb_"));
  EXPECT_FALSE(h.find_token(secret.substr(0, secret.size() - 1)));
  EXPECT_FALSE(h.find_token(secret + "x"));
  std::string flipped = secret;
  flipped[10] = flipped[10] == 'A' ? 'B' : 'A';
  EXPECT_FALSE(h.find_token(flipped));
  EXPECT_TRUE(h.find_token(secret));
}

TEST(HistorianTokens, TheFileHoldsTheHashButNeverTheSecret) {
  const auto path = db_path();
  std::string secret;
  {
    auto h = Historian::open(path);
    secret = h.add_token("alice", Role::admin);
  }
  std::string bytes;
  for (const auto& f : {path, path + "-wal"})
    if (std::filesystem::exists(f)) bytes += read_file_bytes(f);
  const auto hash = sha256(secret);
  // The search can succeed: the hash is there.
  EXPECT_NE(bytes.find(std::string(reinterpret_cast<const char*>(hash.data()), hash.size())), std::string::npos);
  EXPECT_EQ(bytes.find(secret), std::string::npos);
  EXPECT_EQ(bytes.find(secret.substr(4)), std::string::npos);  // nor its random part
  EXPECT_EQ(raw_query_int(path, "SELECT count(*) FROM tokens WHERE length(sha256) = 32"), 1);
}

TEST_P(HistorianTokensTest, NamesAreOneTo64SafeCharactersAndAnActiveNameIsTaken) {
  auto h = Historian::open(location());
  for (const std::string& bad : {std::string(""), std::string(65, 'a'), std::string("a b"), std::string("x/y"),
                                std::string("caf\xc3\xa9"), std::string("a\nb"), std::string("a'b")})
    EXPECT_THROW(h.add_token(bad, Role::viewer), InputError) << bad;
  EXPECT_NO_THROW(h.add_token(std::string(64, 'a'), Role::viewer));
  EXPECT_NO_THROW(h.add_token("Ops.team_1@plant-2", Role::operator_));
  try {
    h.add_token("Ops.team_1@plant-2", Role::admin);
    ADD_FAILURE() << "a taken name was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'Ops.team_1@plant-2' is taken"), std::string::npos) << e.what();
  }
  EXPECT_EQ(h.list_tokens().size(), 2u);
  EXPECT_EQ(h.list_tokens()[0].role, Role::operator_);  // the refused add changed nothing
}

TEST(HistorianTokens, RolesAndJobStatesHaveTheirNames) {
  for (auto r : {Role::viewer, Role::operator_, Role::engineer, Role::admin}) EXPECT_EQ(role_from(to_string(r)), r);
  EXPECT_EQ(to_string(Role::operator_), "operator");
  EXPECT_FALSE(role_from("root"));
  EXPECT_FALSE(role_from("operator_"));
  EXPECT_LT(Role::viewer, Role::operator_);
  EXPECT_LT(Role::engineer, Role::admin);
  for (auto s : {JobStatus::queued, JobStatus::running, JobStatus::done, JobStatus::failed, JobStatus::cancelled})
    EXPECT_EQ(job_status_from(to_string(s)), s);
  EXPECT_EQ(to_string(JobStatus::cancelled), "cancelled");
  EXPECT_FALSE(job_status_from("waiting"));
}

}  // namespace
}  // namespace ambdiag::storage
