// `ambdiag serve --db FILE --http-port N [--domain D]`: the server. DDS
// ingest (server/ingest.h) into the historian in FILE, REST read side on
// port N (0: any free port, printed on stderr); stops cleanly on SIGINT/SIGTERM (ingest drains, the database is
// closed after its last commit).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/proto/stream.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/ingest.h"
#include "ambdiag/server/ingest_group.h"
#include "ambdiag/server/metrics.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/server/retention_service.h"
#include "ambdiag/storage/historian.h"
#include "args.h"
#include "command.h"
#include "serve_parts.h"
#include "serve_ingest_group.h"

namespace ambdiag::cli {

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop = true; }

int integer_in(const Args& args, const std::string& name, double lo, double hi, double def) {
  const auto v = args.number(name);
  if (!v) return static_cast<int>(def);
  if (!(*v >= lo && *v <= hi) || *v != static_cast<double>(static_cast<long>(*v)))
    throw UsageError(name + ": must be an integer in " + std::to_string(static_cast<long>(lo)) + ".." +
                     std::to_string(static_cast<long>(hi)));
  return static_cast<int>(*v);
}

// The server's default alarm rules (docs/service.md "Alarms"): the file's
// rules over the built-in ones. Parsed here; the analysis service checks the
// rules when it is made, so a bad file stops the start with the field named
// before anything listens.
nlohmann::json read_alarm_defaults(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw UsageError("--alarm-defaults: cannot read " + path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError("--alarm-defaults " + path + ": not JSON: " + e.what());
  }
  return j;
}

int run_serve(const std::vector<std::string>& argv) {
  std::set<std::string> options = {"--db", "--http-port", "--domain", "--agent-timeout", "--bench-commit-delay-ms",
                                   "--workers", "--reference-runs", "--alpha", "--tls-cert", "--tls-key", "--rate-limit",
                                   "--rate-limit-burst", "--alarm-defaults", "--durability", "--durable-within",
                                   "--speak-protocol", "--web-dir", "--retention", "--retention-interval", "--parts",
                                   "--instance", "--job-lease", "--db-readers"};
  options.insert(std::begin(kIngestGroupOptionNames), std::end(kIngestGroupOptionNames));
  const Args args(argv, options, {"--quiet", "--bench-inline-checkpoints", "--anonymous-read", "--bench-no-event-notify"});
  args.expect_positional(0, "");
  const auto db = args.option("--db");
  if (!db) throw UsageError("missing --db FILE");
  // The parts this process runs (docs/service.md "Several servers"): an
  // option of a part it does not run is a mistake, not something to ignore.
  const ServeParts parts = parse_serve_parts(args.option("--parts").value_or("ingest,analysis,rest"));
  const std::string instance = serve_instance_name(args.option("--instance").value_or(""));
  const auto not_run = [&](const char* option, const char* part) {
    if (args.option(option))
      throw UsageError(std::string(option) + ": this process runs no " + part + " (--parts " + parts.text() + ")");
  };
  if (!parts.rest) not_run("--http-port", "rest");
  if (!parts.rest) not_run("--db-readers", "rest");
  if (!parts.analysis) not_run("--workers", "analysis");
  if (!parts.analysis) not_run("--retention-interval", "analysis");
  if (parts.rest && !args.option("--http-port")) throw UsageError("missing --http-port N");
  const int http_port = integer_in(args, "--http-port", 0, 65535, 0);
  server::IngestOptions opt;
  opt.domain = integer_in(args, "--domain", 0, 232, 0);
  opt.partitions = ingest_partitions(args);
  opt.agent_timeout = std::chrono::milliseconds(
      static_cast<long>(1000.0 * args.number("--agent-timeout").value_or(10.0)));
  if (opt.agent_timeout.count() <= 0) throw UsageError("--agent-timeout: must be > 0 seconds");
  opt.verbose = !args.flag("--quiet");
  server::IngestGroupOptions group_opt = ingest_group_options(args, opt.verbose);
  group_opt.instance = instance;  // one name for the process: its lease, health, metrics, workers
  opt.commit_delay = std::chrono::milliseconds(integer_in(args, "--bench-commit-delay-ms", 0, 10000, 0));

  storage::CheckpointOptions ckpt;
  const std::string durability = args.option("--durability").value_or("checkpoint");
  if (durability != "checkpoint" && durability != "full")
    throw UsageError("--durability: must be checkpoint or full");
  ckpt.sync_commits = durability == "full";
  const double within_s = args.number("--durable-within").value_or(1.0);
  if (!(within_s >= 0.01 && within_s <= 60)) throw UsageError("--durable-within: must be seconds in 0.01..60");
  ckpt.durable_within = std::chrono::milliseconds(static_cast<long>(1000 * within_s));
  // SQLite's own behaviour for comparison: the writer checkpoints itself
  // every 1000 pages; the thread keeps only the time trigger.
  if (args.flag("--bench-inline-checkpoints")) ckpt.inline_pages = ckpt.trigger_pages;
  if (const auto v = args.option("--speak-protocol")) {
    opt.speak_protocol_minor = stream::minor_of(*v);
    if (!opt.speak_protocol_minor || *opt.speak_protocol_minor < 1)
      throw UsageError("--speak-protocol: must be 1.1 or " + stream::version_string(stream::kProtocolVersion));
  }

  server::AnalysisOptions aopt;
  aopt.db_path = *db;
  aopt.workers = parts.analysis ? integer_in(args, "--workers", 0, 64, 2) : 0;
  aopt.instance = instance;
  const double lease_s = args.number("--job-lease").value_or(10.0);
  if (!(lease_s >= 0.5 && lease_s <= 3600)) throw UsageError("--job-lease: must be seconds in 0.5..3600");
  aopt.job_lease = std::chrono::milliseconds(static_cast<long>(1000 * lease_s));
  aopt.proposed_reference_runs = integer_in(args, "--reference-runs", 1, 100, 3);
  aopt.alpha = args.number("--alpha").value_or(aopt.alpha);
  if (!(aopt.alpha > 0 && aopt.alpha < 0.5)) throw UsageError("--alpha: must be in (0, 0.5)");
  aopt.verbose = opt.verbose;
  const double rate = args.number("--rate-limit").value_or(50);
  if (!(rate >= 0 && rate <= 1e6)) throw UsageError("--rate-limit: must be requests per second in 0..1000000 (0: no limit)");
  const double burst = args.number("--rate-limit-burst").value_or(std::max(1.0, 2 * rate));
  if (!(burst >= 1 && burst <= 1e7)) throw UsageError("--rate-limit-burst: must be in 1..10000000");
  if (const auto file = args.option("--alarm-defaults")) aopt.alarm_defaults = read_alarm_defaults(*file);
  server::RetentionOptions ropt;
  ropt.db_path = *db;
  ropt.verbose = opt.verbose;
  // Checked before anything listens: a bad file names the key (exit 3).
  if (const auto file = args.option("--retention")) ropt.defaults = server::retention_defaults_from_file(*file);
  const double interval_s = args.number("--retention-interval").value_or(600);
  if (!(interval_s == 0 || (interval_s >= 0.1 && interval_s <= 86400 * 7)))
    throw UsageError("--retention-interval: must be seconds in 0.1..604800, or 0 for no periodic sweep");
  ropt.interval = std::chrono::milliseconds(static_cast<long>(1000 * interval_s));

  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);

  // No lock on the file: several servers share it, ingest groups decide
  // which one ingests (docs/streaming.md) and job leases which one runs a
  // job (docs/service.md "Several servers"); a PostgreSQL database the same.
  storage::Historian historian = storage::Historian::open(*db, storage::Historian::Mode::write);
  // Commits (and so acks) never wait for a checkpoint's fsyncs; the
  // checkpoints also say which commits are durable (docs/storage.md).
  if (parts.ingest) historian.checkpoint_in_background(ckpt);
  // What ingest, the analysis and REST count into (GET /metrics); declared
  // first, so it outlives all three.
  server::MetricsRegistry metrics;
  metrics.gauge("ambdiag_instance_info", "This process' instance name and the parts it runs (value 1).",
                {"instance", "parts"})
      .with({instance, parts.text()})
      .set(1);
  aopt.metrics = &metrics;
  ropt.metrics = &metrics;
  // Every process shows and versions policies (REST); only an analysis
  // part sweeps (start() below), the lease keeping it to one at a time.
  server::RetentionService retention(ropt);
  // REST writes and queueing need the service; its workers only run with the analysis part.
  std::optional<server::AnalysisService> analysis;
  if (parts.analysis || parts.rest) analysis.emplace(aopt);
  // A run's analysis job is queued in the commit that makes it complete,
  // wherever the analysis runs; a worker of this process is woken after it.
  opt.in_commit_run_complete = [](storage::Historian& h, const std::string& run_id) { server::queue_run_analysis(h, run_id); };
  if (analysis && aopt.workers > 0)
    opt.on_run_complete = [&analysis](const std::string& run_id) { analysis->notify_run_complete(run_id); };
  // Several servers may name one ingest group: one ingests, the others stand by.
  std::optional<server::IngestGroup> ingest_group;
  if (parts.ingest) {
    ingest_group.emplace(historian, opt, group_opt);
    server::register_ingest_metrics(metrics, ingest_group->ingest());
    server::register_ingest_group_metrics(metrics, *ingest_group);
  }
  const server::Ingest* ingest = ingest_group ? &ingest_group->ingest() : nullptr;
  server::RestOptions rest_opt;
  rest_opt.db_path = *db;
  rest_opt.port = http_port;
  rest_opt.analysis = analysis ? &*analysis : nullptr;
  rest_opt.retention = &retention;
  rest_opt.anonymous_read = args.flag("--anonymous-read");
  rest_opt.db_readers = integer_in(args, "--db-readers", 1, 64, 0);  // 0 (absent): the backend's default
  rest_opt.event_notify = !args.flag("--bench-no-event-notify");  // the poll alone: to measure what NOTIFY saves
  rest_opt.tls_cert_path = args.option("--tls-cert").value_or("");
  rest_opt.tls_key_path = args.option("--tls-key").value_or("");
  if (rest_opt.tls_cert_path.empty() != rest_opt.tls_key_path.empty())
    throw UsageError("--tls-cert and --tls-key go together (HTTPS needs both)");
  rest_opt.proposed_reference_runs = aopt.proposed_reference_runs;
  rest_opt.metrics = &metrics;
  rest_opt.rate_limit_per_s = rate;
  rest_opt.rate_limit_burst = burst;
  // The UI's files: --web-dir, else next to the binary (build tree or install).
  rest_opt.web_dir = args.option("--web-dir").value_or(server::find_web_dir("/proc/self/exe"));
  if (args.option("--web-dir") && !std::filesystem::is_regular_file(rest_opt.web_dir + "/index.html"))
    throw UsageError("--web-dir " + rest_opt.web_dir + ": holds no index.html (build the UI: web/README.md)");
  rest_opt.health_extra = [&ingest_group, &historian, &analysis, &parts, &instance, &retention] {
    const auto ck = historian.checkpoint_stats();
    return nlohmann::json{{"instance", instance},
                          {"parts", parts.names()},
                          {"ingest", ingest_group ? ingest_group->ingest().health() : nlohmann::json(nullptr)},
                          {"ingest_groups", ingest_group ? nlohmann::json::array({ingest_group->health()}) : nlohmann::json::array()},
                          {"jobs", analysis && parts.analysis ? analysis->counters() : nlohmann::json(nullptr)},
                          {"retention", retention.last_sweep()},
                          {"checkpoints", {{"background", ck.background},
                                           {"by_writer", ck.inline_by_writer},
                                           {"pages_copied", ck.pages_copied},
                                           {"time_triggered", ck.time_triggered},
                                           {"commit_generation", ck.commit_generation},
                                           {"durable_generation", ck.durable_generation},
                                           {"errors", ck.errors},
                                           {"last_error", ck.last_error}}}};
  };
  std::optional<server::RestServer> rest;
  int bound_port = 0;
  if (parts.rest) {
    rest.emplace(rest_opt);
    bound_port = rest->start();
  }
  std::fprintf(stderr, "ambdiag serve: instance %s, parts %s, historian %s", instance.c_str(), parts.text().c_str(),
               storage::display_location(*db).c_str());
  if (ingest_group)
    std::fprintf(stderr, ", DDS domain %d, ingest group %s (partitions %s)", opt.domain, group_opt.group.c_str(),
                 ingest_group->status().partitions.c_str());
  if (parts.rest) std::fprintf(stderr, ", REST on port %d%s", bound_port, rest_opt.tls_cert_path.empty() ? "" : " (HTTPS)");
  std::fprintf(stderr, "\n");
  if (parts.rest && !rest_opt.web_dir.empty())
    std::fprintf(stderr, "ambdiag serve: web UI at %s://HOST:%d/ (files in %s)\n", rest_opt.tls_cert_path.empty() ? "http" : "https",
                 bound_port, rest_opt.web_dir.c_str());
  if (analysis) analysis->start();
  if (parts.analysis) retention.start();
  std::thread ingest_thread([&] {
    if (ingest_group) ingest_group->run(g_stop);
  });

  // Progress on stderr every 5 s while something changes.
  int64_t last_blocks = 0, last_rejected = 0;
  auto next_report = std::chrono::steady_clock::now();
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const auto now = std::chrono::steady_clock::now();
    if (now < next_report) continue;
    next_report = now + std::chrono::seconds(5);
    if (!ingest) continue;
    const auto& c = ingest->counters();
    if (c.blocks_stored == last_blocks && c.rejected_total() == last_rejected) continue;
    last_blocks = c.blocks_stored;
    last_rejected = c.rejected_total();
    std::fprintf(stderr, "ambdiag serve: %lld blocks (%.1f MB) committed, %lld duplicates, %lld rejected, %lld runs complete, %lld incomplete\n",
                 static_cast<long long>(c.blocks_stored.load()), static_cast<double>(c.bytes_stored.load()) / 1e6,
                 static_cast<long long>(c.blocks_duplicate.load()), static_cast<long long>(last_rejected),
                 static_cast<long long>(c.runs_complete.load()), static_cast<long long>(c.runs_incomplete.load()));
  }
  std::fprintf(stderr, "ambdiag serve: stopping\n");
  ingest_thread.join();
  if (rest) rest->stop();
  retention.stop();
  if (analysis) analysis->stop();
  if (!ingest) {
    std::fprintf(stderr, "ambdiag serve: stopped\n");
    return kExitOk;
  }
  const auto& c = ingest->counters();
  const auto h = ingest->health();
  std::fprintf(stderr,
               "ambdiag serve: stopped (%lld blocks, %lld bytes committed; %.3f s from the first block received to "
               "the last commit; queue peak %lld bytes; %lld blocks received, %lld duplicates, %lld before their "
               "run's header, %lld refused by the full DDS reader%s)\n",
               static_cast<long long>(c.blocks_stored.load()), static_cast<long long>(c.bytes_stored.load()),
               h.value("streaming_span_s", 0.0), static_cast<long long>(c.queue_peak_bytes.load()),
               static_cast<long long>(c.blocks_received.load()), static_cast<long long>(c.blocks_duplicate.load()),
               static_cast<long long>(c.blocks_orphan.load()), static_cast<long long>(c.blocks_rejected_by_dds.load()),
               opt.speak_protocol_minor.value_or(stream::kDurableAckMinor) >= stream::kDurableAckMinor
                   ? ("; " + std::to_string(c.blocks_acked_durable.load()) + " blocks acknowledged durable").c_str()
                   : "");
  return kExitOk;
}

}  // namespace

std::vector<Command> serve_commands() {
  return {{{"serve"},
           "the server: DDS ingest into the historian, REST read side",
           "usage: ambdiag serve --db FILE --http-port N [--domain D] [--partition NAME] [--agent-timeout S] [--tls-cert F --tls-key F] [--quiet]\n"
           "                     [--ingest-group NAME] [--ingest-partitions P,...] [--ingest-lease S]\n"
           "                     [--durability checkpoint|full] [--durable-within S]\n"
           "                     [--anonymous-read] [--workers N] [--reference-runs N] [--alpha P]\n"
           "                     [--rate-limit N] [--rate-limit-burst B] [--alarm-defaults FILE] [--web-dir DIR]\n"
           "                     [--retention FILE] [--retention-interval S]\n"
           "                     [--parts ingest,analysis,rest] [--instance NAME] [--job-lease S] [--db-readers N]\n"
           "\n"
           "Receives runs from every ambdiag-agent in DDS domain D (default 0), all partitions\n"
           "(sites) unless --partition is given, stores them in the historian FILE and serves\n"
           "the REST read side on port N. A run whose agent falls silent for S seconds\n"
           "(default 10) before its end is marked incomplete. SIGINT/SIGTERM stop it cleanly.\n"
           "Every complete identification run of a pump with a model is analysed by N worker\n"
           "threads (--workers, default 2; 0: store only) at idle priority: FRF, modal fit, detection\n"
           "against the pump's reference at false-alarm rate P per run (--alpha, default 1e-5), diagnosis.\n"
           "Without a reference the first N complete identification runs are proposed (--reference-runs,\n"
           "default 3). Every request but health needs a token (ambdiag token add); --anonymous-read lets\n"
           "requests without one read as viewer.\n"
           "FILE may be a PostgreSQL database instead: --db postgresql://USER@HOST/DB (a libpq URI;\n"
           "  docs/storage.md \"PostgreSQL\"), created there at the first start.\n"
           "--ingest-group NAME (default: default): servers naming one group on one database ingest its partitions\n"
           "  (--partition SITE: SITE,SITE/*; or --ingest-partitions P1,P2 of DDS partition names or patterns; default *)\n"
           "  one at a time: the holder renews a lease of S seconds (--ingest-lease, default 3), a standby takes over\n"
           "  when it lapses (docs/streaming.md).\n"
           "--rate-limit N: requests per second per token (per client address without one), in bursts of\n"
           "  B (--rate-limit-burst, default 2N); beyond: 429 with Retry-After. Default 50; 0: no limit.\n"
           "  Health and /metrics are not limited. GET /metrics: Prometheus metrics; GET /api/v1/events:\n"
           "  live updates (server-sent events); GET /api/v1/openapi.json: every route.\n"
           "Each analysed run is evaluated against the pump's alarm rules; --alarm-defaults FILE: the server's\n"
           "default rules (JSON {\"rules\": [...], \"plant_state\"?}, each rule over the built-in one of its id;\n"
           "docs/service.md \"Alarms\"), checked at the start.\n"
           "--retention FILE: the server's default retention policy (JSON {\"samples_days\"?, \"samples_bytes\"?,\n"
           "  \"frf_days\"?, \"monitoring_days\"?}, each over the built-in one: samples 90 days, FRFs 730 days,\n"
           "  monitoring kept; null: kept for ever), checked at the start; each pump's own policy over it:\n"
           "  PUT /api/v1/pumps/{id}/retention. An analysis part sweeps 2 s after the start and every S seconds\n"
           "  (--retention-interval, default 600; 0: never, `ambdiag db retention` sweeps), one process at a time\n"
           "  on a database. docs/storage.md.\n"
           "--web-dir DIR: the web UI's built files, served at / without a token (default: ../web or\n"
           "  ../share/ambdiag/web next to this binary; web/README.md).\n"
           "--parts LIST: what this process runs, any of ingest, analysis, rest (default all three); any number\n"
           "  of processes may share FILE (docs/service.md \"Several servers\"). Without\n"
           "  rest no port is opened (--http-port refused); without analysis no job runs here and no\n"
           "  retention sweep (--workers, --retention-interval refused).\n"
           "--instance NAME: this process' name in health, metrics, its jobs' `worker` and its ingest group's lease\n"
           "  (default HOST:PID).\n"
           "--job-lease S: a claimed job is held S seconds (default 10) and renewed every S/3; a job whose\n"
           "  worker died or stalled is queued again by any analysis process once its lease expired.\n"
           "--bench-commit-delay-ms N delays every commit (emulates a slow disk; benchmarks only).\n"
           "--bench-inline-checkpoints: SQLite's own checkpoints in the committing thread instead of the background\n"
           "  checkpoint thread (for comparison; benchmarks only).\n"
           "--db-readers N: read connections the REST workers share (1..64; default one per worker, 64, on\n"
           "  SQLite, 16 on PostgreSQL, where each is a server process: docs/deployment.md \"Connections\").\n"
           "--bench-no-event-notify: PostgreSQL: the event streams poll the events table every 250 ms only, without\n"
           "  LISTEN/NOTIFY (for comparison; benchmarks only).\n"
           "--durability checkpoint|full: how blocks become durable before agents may delete them (protocol 1.2):\n"
           "  checkpoint (default): a checkpoint syncs the log, at the latest --durable-within S seconds (default 1)\n"
           "  after the commit; full: synchronous=FULL, every commit fsyncs the log (docs/storage.md, Durability).\n"
           "--speak-protocol 1.1: acknowledge as a 1.1 server did (committed only; for version tests).\n"
           "--tls-cert FILE --tls-key FILE: the REST port speaks HTTPS only (TLS 1.2 or later), PEM files\n"
           "  (deploy/security/ambdiag-pki.sh tls); a missing, unreadable or mismatched file: exit 3.\n"
           "Set CYCLONEDDS_URI to a Cyclone config (deploy/cyclonedds/local.xml on one machine); with DDS\n"
           "Security, append the server's security.xml (deploy/security/ambdiag-pki.sh, docs/streaming.md).\n",
           run_serve}};
}

}  // namespace ambdiag::cli
