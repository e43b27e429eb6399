// `ambdiag db import|export|list`: run recordings in and out of the historian
// (storage/recording_io.h); `ambdiag db retention`: one retention sweep
// (storage/retention.h).
#include <cstdio>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/server/retention_service.h"
#include "ambdiag/storage/historian.h"
#include "ambdiag/storage/recording_io.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

int run_db_import(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db", "--chunk-bytes"}, {"--json"});
  args.expect_positional(1, "RUN_DIR");
  std::size_t chunk_bytes = 32768;
  if (const auto n = args.number("--chunk-bytes")) {
    if (!(*n >= 4 && *n <= (64 << 20))) throw UsageError("--chunk-bytes: must be in 4..67108864");
    chunk_bytes = static_cast<std::size_t>(*n);
  }
  auto h = storage::Historian::open(args.required("--db", "FILE"));
  const auto res = storage::import_recording(h, args.positional()[0], chunk_bytes);
  const std::string status = storage::to_string(res.end.status);
  if (args.flag("--json")) {
    std::cout << nlohmann::json{{"run_id", res.run_id},
                                {"status", status},
                                {"status_reason", res.end.reason},
                                {"chunks", res.chunks},
                                {"duplicates", res.duplicates},
                                {"frames", res.end.frames_held}}
                     .dump(2)
              << "\n";
  } else {
    std::printf("%s: %s, %lld chunks (%lld already held), %lld frames\n", res.run_id.c_str(), status.c_str(),
                static_cast<long long>(res.chunks), static_cast<long long>(res.duplicates),
                static_cast<long long>(res.end.frames_held));
  }
  return res.end.status == storage::RunStatus::complete ? kExitOk : kExitBadInput;
}

int run_db_export(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db", "-o"}, {"--incomplete"});
  args.expect_positional(1, "RUN_ID");
  const auto out = args.option("-o");
  if (!out) throw UsageError("missing -o DIR");
  auto h = storage::Historian::open(args.required("--db", "FILE"), storage::Historian::Mode::read);
  storage::export_recording(h, args.positional()[0], *out, args.flag("--incomplete"));
  std::fprintf(stderr, "wrote %s\n", out->c_str());
  return kExitOk;
}

int run_db_list(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db"}, {"--json"});
  args.expect_positional(0, "nothing");
  auto h = storage::Historian::open(args.required("--db", "FILE"), storage::Historian::Mode::read);
  auto snap = h.snapshot();
  nlohmann::json pumps = nlohmann::json::array();
  for (const auto& p : h.list_pumps()) {
    nlohmann::json runs = nlohmann::json::array();
    for (const auto& r : h.list_runs(p.pump_id)) {
      runs.push_back({{"run_id", r.run_id},
                      {"started_at", r.started_at},
                      {"status", storage::to_string(r.status)},
                      {"status_reason", r.status_reason},
                      {"frames", r.received_frames},
                      {"samples", r.samples_dropped_at ? "dropped" : "held"}});
    }
    pumps.push_back({{"pump_id", p.pump_id}, {"runs", runs}});
  }
  if (args.flag("--json")) {
    std::cout << nlohmann::json{{"pumps", pumps}}.dump(2) << "\n";
    return kExitOk;
  }
  for (const auto& p : pumps) {
    std::printf("%s\n", p["pump_id"].get<std::string>().c_str());
    for (const auto& r : p["runs"])
      std::printf("  %-40s %-10s %lld frames%s %s\n", r["run_id"].get<std::string>().c_str(),
                  r["status"].get<std::string>().c_str(), r["frames"].get<long long>(),
                  r["samples"] == "dropped" ? " (samples dropped by retention)" : "",
                  r["status_reason"].get<std::string>().c_str());
  }
  return kExitOk;
}

// One sweep with the server's defaults (--retention FILE, else the built-in
// ones) and each pump's own policy from the file; beside a running server
// (its own write connection; the lease keeps two sweeps apart).
int run_db_retention(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db", "--retention"}, {"--dry-run", "--json"});
  args.expect_positional(0, "nothing");
  const std::string db = args.required("--db", "FILE");
  const auto defaults = args.option("--retention") ? server::retention_defaults_from_file(*args.option("--retention"))
                                                   : storage::RetentionPolicy{};
  storage::SweepOptions opt;
  opt.dry_run = args.flag("--dry-run");
  auto h = storage::Historian::open(db, opt.dry_run ? storage::Historian::Mode::read : storage::Historian::Mode::write);
  const storage::SweepReport r = h.sweep_retention(defaults, opt);
  if (args.flag("--json")) {
    std::cout << storage::to_json(r, true).dump(2) << "\n";
  } else if (r.skipped.empty()) {
    for (const auto& run : r.runs)
      std::printf("%-8s %-40s %10.3f MB  %s\n", run.what.c_str(), run.run_id.c_str(), static_cast<double>(run.bytes) / 1e6,
                  run.reason.c_str());
    std::printf("%s the samples of %lld runs (%.1f MB), %lld day partitions whole (%lld kept runs, %.1f MB, moved out "
                "first), the FRFs of %lld runs (%.1f MB), %lld monitoring snapshots; %.2f s, longest transaction %.3f s\n",
                opt.dry_run ? "would drop" : "dropped", static_cast<long long>(r.samples_runs),
                static_cast<double>(r.samples_bytes) / 1e6, static_cast<long long>(r.partitions),
                static_cast<long long>(r.moved_runs), static_cast<double>(r.moved_bytes) / 1e6,
                static_cast<long long>(r.frf_runs), static_cast<double>(r.frf_bytes) / 1e6,
                static_cast<long long>(r.monitoring_rows), r.seconds, r.longest_transaction_s);
  }
  for (const auto& e : r.errors) std::fprintf(stderr, "ambdiag db retention: %s\n", e.c_str());
  if (!r.skipped.empty()) {
    std::fprintf(stderr, "ambdiag db retention: %s; nothing dropped\n", r.skipped.c_str());
    return kExitBadInput;
  }
  return kExitOk;
}

}  // namespace

std::vector<Command> db_commands() {
  return {
      {{"db", "import"},
       "store a run recording folder in the historian",
       "usage: ambdiag db import RUN_DIR --db FILE [--chunk-bytes N] [--json]\n\n"
       "Checks the recording, stores run.json verbatim and samples.f32 in chunks of whole frames\n"
       "(about N bytes, default 32768), then verifies frame count and checksum like a streamed run.\n"
       "Importing the same run again stores nothing twice. Creates FILE if missing.\n"
       "Exit 0 when the run is complete, 3 otherwise or on bad input.\n",
       run_db_import},
      {{"db", "export"},
       "write a run of the historian as a recording folder",
       "usage: ambdiag db export RUN_ID --db FILE -o DIR [--incomplete]\n\n"
       "Writes DIR/run.json and DIR/samples.f32 bit-identical to what was received, atomically\n"
       "(a temporary folder renamed into place). DIR must not exist or be empty.\n"
       "  --incomplete  also export a run that is not complete (its chunks as held)\n",
       run_db_export},
      {{"db", "list"},
       "pumps and runs held in the historian",
       "usage: ambdiag db list --db FILE [--json]\n",
       run_db_list},
      {{"db", "retention"},
       "one retention sweep: drop what the pumps' retention policies no longer keep",
       "usage: ambdiag db retention --db FILE|postgresql://... [--retention FILE] [--dry-run] [--json]\n\n"
       "Drops the raw samples, the analyses' files (frf.csv, figures) and the monitoring snapshots that\n"
       "each pump's policy (PUT /api/v1/pumps/{id}/retention) over the defaults no longer keeps, and prints\n"
       "what it dropped, run by run. The defaults: --retention FILE (as `ambdiag serve --retention`), else\n"
       "the built-in ones (samples 90 days, FRFs 730 days, monitoring kept). Reference runs and runs an\n"
       "open alarm or a queued or running job names are never dropped. Works beside running servers (one\n"
       "sweep at a time on a database). On PostgreSQL a past day's partition of samples none of whose runs\n"
       "is kept is dropped whole (docs/storage.md \"Retention\").\n"
       "  --dry-run  print what would be dropped, change nothing\n"
       "  --json     {\"samples\": {\"runs\", \"bytes\"}, \"frf\": {...}, \"monitoring_rows\", \"runs\": [...], ...}\n"
       "Exit 3 when another sweep holds the retention lease (nothing dropped).\n",
       run_db_retention},
  };
}

}  // namespace ambdiag::cli
