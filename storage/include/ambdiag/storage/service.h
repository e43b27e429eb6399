// What the server keeps besides runs (schema v4, docs/storage.md): each
// pump's plant models and references (versioned, every version kept), the
// job queue with the jobs' results and files, and the API tokens. The
// Historian's methods that read and write them are declared in historian.h
// and implemented in historian_{registry,jobs,tokens}.cc; no SQL leaves
// storage/, so another backend (PostgreSQL) plugs in behind the same calls.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace ambdiag::storage {

// One version of a pump's plant model (../shared/specs/plant-model.md).
struct ModelVersion {
  std::string pump_id;
  int version = 0;           // 1, 2, ... per pump
  std::string plant_json;    // as PUT, byte for byte
  std::string created_at;    // server clock, ISO 8601 UTC
  std::string created_by;    // the token's name ("" from the command line)
  std::string comment;       // e.g. "adopted from explain job 17"
};

// One version of a pump's reference: the runs that show its healthy state.
struct ReferenceVersion {
  std::string pump_id;
  int version = 0;  // 1, 2, ... per pump
  std::vector<std::string> run_ids;
  std::string created_at, created_by;
};

enum class JobStatus { queued, running, done, failed, cancelled };
std::string to_string(JobStatus s);
std::optional<JobStatus> job_status_from(const std::string& s);

// What makes a job unique: one job per (kind, run, model version, reference
// version). Absent values are stored as 0 / "" and compare equal.
struct JobKey {
  std::string kind;    // "analysis", "reference", "explain"
  std::string pump_id;
  std::string run_id;  // "" for jobs of a pump (reference)
  int model_version = 0;
  int reference_version = 0;
};

struct Job {
  std::int64_t job_id = 0;
  JobKey key;
  JobStatus status = JobStatus::queued;
  double progress = 0.0;  // 0..1
  int attempts = 0;       // claims so far; the running attempt's number while running
  std::string params_json = "{}";  // what the job needs besides its key
  std::optional<std::int64_t> depends_on;  // claimed only once that job is done
  std::string created_at;
  std::optional<std::string> started_at, finished_at;  // of the last attempt
  std::optional<std::string> error;
  std::optional<std::string> result_json;  // done jobs
  std::string worker;     // who holds the running attempt
  // While running: until when the attempt holds the job (server clock, ISO
  // 8601 UTC with milliseconds); nullopt otherwise.
  std::optional<std::string> lease_expires_at;
};

// How long a claim holds a job without a renewal (`ambdiag serve --job-lease`).
inline constexpr std::chrono::milliseconds kDefaultJobLease{10000};

// A file a job produced (FRF with sigma, SVG plots, a learnt reference),
// stored with its result in the same transaction.
struct JobArtifact {
  std::string name;          // e.g. "frf.csv", "bode.svg"
  std::string content_type;  // e.g. "text/csv", "image/svg+xml"
  std::string data;          // bytes
};

struct JobFilter {
  std::optional<std::string> pump_id, run_id, kind;
  std::optional<JobStatus> status;
  int limit = 1000;  // newest first
};

enum class Role { viewer = 0, operator_ = 1, engineer = 2, admin = 3 };
std::string to_string(Role r);  // "viewer", "operator", "engineer", "admin"
std::optional<Role> role_from(const std::string& s);

struct TokenInfo {
  std::string name;
  Role role = Role::viewer;
  std::string created_at;
  std::optional<std::string> revoked_at;
};

}  // namespace ambdiag::storage
