// The historian's schema: pragmas, migrations keyed by PRAGMA user_version.
#pragma once

#include "sql/sqlite/sqlite_db.h"

namespace ambdiag::storage::detail {

// 'AMBD': marks the file as an ambdiag historian (PRAGMA application_id).
inline constexpr int kApplicationId = 0x414D4244;

// One step of a schema's history: the SQL that takes it to `version`
// (schema.cc for SQLite, sql/postgres/pg_schema.cc for PostgreSQL).
struct Migration {
  int version;
  const char* sql;
};

int latest_schema_version();
// Sets the connection pragmas (docs/storage.md says why each).
void set_pragmas(Db& db, bool read_only);
// Writer: applies every missing migration, each in its own transaction.
// Reader: checks the schema is current. Both refuse a file that is another
// application's database or has a newer schema than this program.
void migrate(Db& db, bool read_only);

}  // namespace ambdiag::storage::detail
