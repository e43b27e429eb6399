// For the benchmarks on PostgreSQL (bench_pg_ingest, bench_jobs): a bare
// libpq connection for the set-up (schemas, settings), and the historian
// location of a schema of the database a URI names.
#pragma once

#include <libpq-fe.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace ambdiag::bench {

[[noreturn]] inline void pg_die(const char* program, const std::string& what) {
  std::fprintf(stderr, "%s: %s\n", program, what.c_str());
  std::exit(1);
}

struct PgConn {
  const char* program;
  PGconn* c;
  PgConn(const char* prog, const std::string& uri) : program(prog), c(PQconnectdb(uri.c_str())) {
    if (PQstatus(c) != CONNECTION_OK) pg_die(program, std::string("connect: ") + PQerrorMessage(c));
    PQsetNoticeProcessor(c, [](void*, const char*) {}, nullptr);
  }
  ~PgConn() { PQfinish(c); }
  PgConn(const PgConn&) = delete;
  PgConn& operator=(const PgConn&) = delete;
  // The first column of the first row ("" for none); exits on an error.
  std::string exec(const std::string& sql) const {
    PGresult* r = PQexec(c, sql.c_str());
    const auto st = PQresultStatus(r);
    if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) pg_die(program, sql.substr(0, 60) + ": " + PQresultErrorMessage(r));
    std::string v = st == PGRES_TUPLES_OK && PQntuples(r) > 0 ? PQgetvalue(r, 0, 0) : "";
    PQclear(r);
    return v;
  }
};

// The historian location of `schema` in the database of `uri`.
inline std::string pg_schema_location(const std::string& uri, const std::string& schema, const std::string& app) {
  const std::string sep = uri.find('?') == std::string::npos ? "?" : "&";
  return uri + sep + "options=-csearch_path%3D" + schema + "&application_name=" + app;
}

}  // namespace ambdiag::bench
