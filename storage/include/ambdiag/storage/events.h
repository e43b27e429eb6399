// The events table (schema v8): what GET /api/v1/events streams, kept in
// the database so that every server on it streams the same events with the
// same ids (docs/service.md "Several servers"). An event is written in the
// transaction of what it announces (a run's status, a job's result, an
// alarm transition, a model), so it exists exactly when that happened.
// The Historian's calls are in historian.h ("events").
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace ambdiag::storage {

struct StoredEvent {
  std::int64_t seq = 0;   // grows with each event, never reused; the SSE id
  std::string time;       // server clock, ISO 8601 UTC with milliseconds
  std::string type;       // "run.new", "job.done", ...
  std::string pump_id;    // "" for events of no pump
  std::string data_json;  // a JSON object on one line
};

// The table is bounded: append_event prunes, every kEventsPruneEvery
// events, all but the newest kEventsKeepRows and those older than
// kEventsKeep. A client that reconnects later than that is told to reload.
inline constexpr std::int64_t kEventsKeepRows = 100000;
inline constexpr std::chrono::hours kEventsKeep{24};
inline constexpr std::int64_t kEventsPruneEvery = 256;

}  // namespace ambdiag::storage
