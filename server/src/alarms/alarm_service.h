// The alarm side of the analysis service: its own writer connection for
// what people do to alarms (rules, acknowledge, shelve, reset), and a timer
// thread for what the clock does (shelves that expire, stale data), so both
// happen without requests. Runs are evaluated by the job runners
// (alarm_evaluator.h), each on its own connection; SQLite's write lock
// serialises them with this one.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "alarms/alarm_evaluator.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

class AlarmService {
 public:
  // `defaults`: a validated full rule set (alarm_rules.h).
  AlarmService(const std::string& db_path, const nlohmann::json& defaults, AlarmEventSink sink, int tick_ms, int stale_check_s);
  ~AlarmService();
  AlarmService(const AlarmService&) = delete;
  AlarmService& operator=(const AlarmService&) = delete;

  // Evaluates what a dead server left unevaluated, then starts the timer.
  void start();
  void stop();

  // PUT .../alarm-rules: a new version; InputError naming the field.
  // Returns the effective rules (as GET shows them).
  nlohmann::json put_rules(const std::string& pump_id, const nlohmann::json& body, const std::string& by);
  // The alarm after the action; NotFoundError, ConflictError, InputError.
  nlohmann::json acknowledge(std::int64_t alarm_id, const std::string& by, const std::string& comment);
  nlohmann::json shelve(std::int64_t alarm_id, std::int64_t minutes, const std::string& by, const std::string& comment);
  nlohmann::json unshelve(std::int64_t alarm_id, const std::string& by, const std::string& comment);
  nlohmann::json reset(std::int64_t alarm_id, const std::string& by, const std::string& comment);

 private:
  template <class F>
  nlohmann::json act(std::int64_t alarm_id, F&& action);
  void timer_loop();

  const nlohmann::json& defaults_;
  int tick_ms_, stale_check_s_;
  std::mutex mu_;  // guards h_ and ev_
  storage::Historian h_;
  AlarmEvaluator ev_;
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  std::thread timer_;
};

// GET .../alarm-rules: the pump's effective rules with their version
// ("source": "pump" or "defaults").
nlohmann::json alarm_rules_view(storage::Historian& h, const std::string& pump_id, const nlohmann::json& defaults);

}  // namespace ambdiag::server::detail
