// `ambdiag serve`'s ingest side across servers (docs/streaming.md "Several
// servers: ingest groups and failover"): which DDS partitions this server
// ingests, in which ingest group, with which lease.
#pragma once

#include <string>
#include <vector>

#include "ambdiag/server/ingest_group.h"
#include "args.h"

namespace ambdiag::cli {

// The options read here (serve's option list includes them).
inline const char* const kIngestGroupOptionNames[] = {"--partition", "--ingest-partitions", "--ingest-group",
                                                      "--ingest-lease"};

// --partition SITE: SITE and its pumps' SITE/* (docs/streaming.md
// "Security"); --ingest-partitions P1,P2,...: those DDS partition names or
// patterns; neither: "*" (every site). UsageError naming the option.
std::vector<std::string> ingest_partitions(const Args& args);
// --ingest-group NAME (default "default"), --ingest-lease S (default 3);
// the instance is serve's (serve_parts.h: --instance, default HOST:PID).
server::IngestGroupOptions ingest_group_options(const Args& args, bool verbose);

}  // namespace ambdiag::cli
