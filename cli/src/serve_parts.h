// What one `ambdiag serve` process runs (docs/service.md "Several
// servers"): `--parts ingest,analysis,rest` (all three by default) and the
// name it is known by (`--instance`, default HOST:PID), shown in health,
// metrics and as its job workers' names.
#pragma once

#include <string>
#include <vector>

namespace ambdiag::cli {

struct ServeParts {
  bool ingest = true, analysis = true, rest = true;
  // "ingest,analysis,rest" in that order, the parts run.
  std::string text() const;
  std::vector<std::string> names() const;
};

// A comma-separated non-empty list of ingest, analysis, rest (each at most
// once); UsageError naming the bad part ("--parts: unknown part 'rst'").
ServeParts parse_serve_parts(const std::string& list);

// `--instance NAME`: 1 to 64 of A-Z a-z 0-9 . _ : @ - (it goes into logs,
// metrics labels and job rows); UsageError otherwise. Empty: HOST:PID.
std::string serve_instance_name(const std::string& given);

}  // namespace ambdiag::cli
