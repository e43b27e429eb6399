// Historian, PostgreSQL only: sample_chunks' day partitions (docs/storage.md
// "Retention", "PostgreSQL: day partitions"). Every chunk carries its run's
// reception time (run_created_at); a partition holds the chunks of the runs
// received on one UTC day, so that retention drops a day whole (DROP TABLE:
// no dead rows, the space back at once) once no run of it is kept.
// Partitions are made ahead (today and the next two days) when a writer
// opens, at a begin_run outside a transaction once a day, and at each sweep:
// a range must exist before its first chunk, else the chunk goes to
// sample_chunks_default and the day stays there (swept row by row).
#include <ctime>

#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

constexpr int kDaysAhead = 2;

// "20261126" of the UTC day of t + days.
std::string day_key(std::chrono::system_clock::time_point t, int days = 0) {
  const std::time_t s = std::chrono::system_clock::to_time_t(t) + static_cast<std::time_t>(days) * 86400;
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[16];
  std::strftime(buf, sizeof buf, "%Y%m%d", &tm);
  return buf;
}

// "20261126" -> "2026-11-26T00:00:00.000Z" (created_at's format).
std::string day_start(const std::string& key) {
  return key.substr(0, 4) + "-" + key.substr(4, 2) + "-" + key.substr(6, 2) + "T00:00:00.000Z";
}

std::string next_day_key(const std::string& key) {
  std::tm tm{};
  tm.tm_year = std::stoi(key.substr(0, 4)) - 1900;
  tm.tm_mon = std::stoi(key.substr(4, 2)) - 1;
  tm.tm_mday = std::stoi(key.substr(6, 2)) + 1;  // timegm normalises the 32nd
  return day_key(std::chrono::system_clock::from_time_t(timegm(&tm)));
}

constexpr const char* kPrefix = "sample_chunks_d";

}  // namespace

std::vector<Historian::Impl::ChunkPartition> Historian::Impl::chunk_partitions() {
  auto& s = stmt(
      "SELECT CAST(c.relname AS text) FROM pg_catalog.pg_inherits i JOIN pg_catalog.pg_class c ON c.oid = i.inhrelid "
      "JOIN pg_catalog.pg_class p ON p.oid = i.inhparent JOIN pg_catalog.pg_namespace n ON n.oid = p.relnamespace "
      "WHERE n.nspname = current_schema() AND p.relname = 'sample_chunks' AND c.relname LIKE 'sample_chunks_d%' "
      "ORDER BY 1");
  std::vector<ChunkPartition> out;
  while (s.step()) {
    const std::string name = s.col_text(0);
    const std::string key = name.substr(std::char_traits<char>::length(kPrefix));
    if (key.size() != 8) continue;  // not one of ours
    out.push_back({name, day_start(key), day_start(next_day_key(key))});
  }
  return out;
}

void Historian::Impl::ensure_chunk_partitions(std::chrono::system_clock::time_point now) {
  if (dialect() != Dialect::postgres || read_only || db.in_transaction()) return;
  const std::string last = day_key(now, kDaysAhead);
  if (partitions_through >= last) return;  // done today by this process
  for (int d = 0; d <= kDaysAhead; ++d) {
    const std::string key = day_key(now, d);
    const std::string name = kPrefix + key, from = day_start(key), to = day_start(next_day_key(key));
    Transaction tx(db, Transaction::Kind::write);
    lock(LockSpace::partitions, "sample_chunks");  // one creator at a time; the others then see it
    auto& exists = stmt(
        "SELECT count(*) FROM pg_catalog.pg_class c JOIN pg_catalog.pg_namespace n ON n.oid = c.relnamespace "
        "WHERE n.nspname = current_schema() AND CAST(c.relname AS text) = ?");
    exists.bind(1, name).step();
    const bool made = exists.col_int(0) > 0;
    exists.reset();
    if (made) continue;  // the transaction ends without a change
    // PostgreSQL refuses a range whose rows the default partition holds:
    // such a day stays in the default partition.
    auto& in_default = stmt(
        "SELECT count(*) FROM (SELECT 1 FROM sample_chunks_default WHERE run_created_at >= CAST(? AS timestamptz) "
        "AND run_created_at < CAST(? AS timestamptz) LIMIT 1) x");
    in_default.bind(1, from).bind(2, to).step();
    const bool held = in_default.col_int(0) > 0;
    in_default.reset();
    if (held) continue;
    db.exec(("CREATE TABLE " + name + " PARTITION OF sample_chunks FOR VALUES FROM ('" + from + "') TO ('" + to +
             "'); ALTER TABLE " + name + " ALTER COLUMN data SET STORAGE EXTERNAL")
                .c_str(),
            "create a day partition of sample_chunks");
    tx.commit();
  }
  partitions_through = last;
}

}  // namespace ambdiag::storage
