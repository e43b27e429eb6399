// A peek at a historian file with the plain SQLite C API, beside the
// running servers (the default VFS: this process never installs another).
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <string>

namespace ambdiag::testing {

// One value of a query on the file ("?" when there is none).
inline std::string sql_text(const std::filesystem::path& db, const std::string& sql) {
  sqlite3* h = nullptr;
  sqlite3_open(db.c_str(), &h);
  sqlite3_stmt* s = nullptr;
  std::string v = "?";
  if (sqlite3_prepare_v2(h, sql.c_str(), -1, &s, nullptr) == SQLITE_OK && sqlite3_step(s) == SQLITE_ROW &&
      sqlite3_column_text(s, 0))
    v = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  sqlite3_finalize(s);
  sqlite3_close(h);
  return v;
}
inline int64_t sql_int(const std::filesystem::path& db, const std::string& sql) {
  const std::string v = sql_text(db, sql);
  return v == "?" ? -1 : std::stoll(v);
}

inline std::string sql_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

}  // namespace ambdiag::testing
