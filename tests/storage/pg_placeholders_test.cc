// The historian's SQL placeholders (SQLite's ? and ?N) as PostgreSQL's $n,
// rewritten once per statement (storage/src/sql/postgres/pg_db.h).
#include <gtest/gtest.h>

#include "sql/postgres/pg_db.h"

namespace ambdiag::storage::detail {
namespace {

TEST(PgPlaceholders, PlainOnesCountFromOne) {
  EXPECT_EQ(numbered_placeholders("INSERT INTO t (a, b) VALUES (?, ?)"), "INSERT INTO t (a, b) VALUES ($1, $2)");
  EXPECT_EQ(numbered_placeholders("SELECT 1"), "SELECT 1");
}

TEST(PgPlaceholders, NumberedOnesKeepTheirNumberAndAPlainOneFollowsTheHighest) {
  EXPECT_EQ(numbered_placeholders("WHERE (a = ?1 OR ?1 IS NULL) AND b = ?12 LIMIT ?"),
            "WHERE (a = $1 OR $1 IS NULL) AND b = $12 LIMIT $13");
}

TEST(PgPlaceholders, QuotedTextAndIdentifiersAreLeftAlone) {
  EXPECT_EQ(numbered_placeholders("SELECT '?', 'it''s ?', \"col?\" FROM t WHERE x = ?"),
            "SELECT '?', 'it''s ?', \"col?\" FROM t WHERE x = $1");
}

}  // namespace
}  // namespace ambdiag::storage::detail
