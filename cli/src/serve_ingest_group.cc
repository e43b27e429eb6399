#include "serve_ingest_group.h"


namespace ambdiag::cli {

std::vector<std::string> ingest_partitions(const Args& args) {
  const auto site = args.option("--partition");
  const auto list = args.option("--ingest-partitions");
  if (site && list) throw UsageError("--partition and --ingest-partitions: give one (--partition S is S,S/*)");
  if (site) return {*site, *site + "/*"};  // the site and its pumps' own partitions
  if (!list) return {"*"};
  std::vector<std::string> out;
  size_t from = 0;
  for (;;) {
    const size_t comma = list->find(',', from);
    out.push_back(list->substr(from, comma == std::string::npos ? std::string::npos : comma - from));
    if (out.back().empty()) throw UsageError("--ingest-partitions: an empty name in '" + *list + "'");
    if (comma == std::string::npos) break;
    from = comma + 1;
  }
  return out;
}

server::IngestGroupOptions ingest_group_options(const Args& args, bool verbose) {
  server::IngestGroupOptions g;
  g.group = args.option("--ingest-group").value_or("default");
  if (g.group.empty() || g.group.size() > 128) throw UsageError("--ingest-group: a name of 1 to 128 characters");
  const double lease_s = args.number("--ingest-lease").value_or(3.0);
  if (!(lease_s >= 0.3 && lease_s <= 600)) throw UsageError("--ingest-lease: must be seconds in 0.3..600");
  g.lease = std::chrono::milliseconds(static_cast<long>(1000 * lease_s));
  g.verbose = verbose;
  return g;
}

}  // namespace ambdiag::cli
