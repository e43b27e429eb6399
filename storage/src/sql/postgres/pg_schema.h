// The historian's schema in PostgreSQL (pg_schema.cc): created at the
// current version, migrated like SQLite's files, version in ambdiag_schema.
#pragma once

#include "sql/postgres/pg_db.h"

namespace ambdiag::storage::detail {

int pg_latest_schema_version();
// Writer: creates the schema in the connection's current schema (the first
// of search_path) or applies the missing migrations, in one transaction.
// Reader: checks it is current. Both refuse (InputError naming the
// location) a database that is not UTF8, has tables without the ambdiag
// mark, or a newer schema than this program.
void pg_migrate(PgDb& db, bool read_only);

}  // namespace ambdiag::storage::detail
