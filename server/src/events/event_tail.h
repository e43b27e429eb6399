// Each REST process' view of the historian's events table (storage/events.h;
// docs/service.md "Several servers"): one thread reads the events after the
// last one it saw, every poll period, and publishes them into the process'
// EventBus, so every open stream gets them from one query, whichever
// process wrote them. The bus is primed with the newest events held (its
// ring) and reads older ones from the table for a client that reconnects
// with an older Last-Event-ID (EventBus::set_history).
//
// On PostgreSQL a second thread waits on an EventListener (LISTEN on the
// channel append_event NOTIFYs at its commit) and calls wake(), which polls
// at once: an event reaches the streams within milliseconds of its commit on
// any server, and the period is the fallback (a lost notification, the
// listener's connection down until it reconnects and catches up by seq).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include "ambdiag/server/events.h"
#include "ambdiag/storage/event_listener.h"
#include "ambdiag/storage/historian.h"
#include "reader_pool.h"

namespace ambdiag::server::detail {

class EventTail {
 public:
  // Opens its read connection (InputError as Historian::open) and, on
  // PostgreSQL with `listen`, its listening one.
  EventTail(const std::string& db_path, EventBus& bus, std::chrono::milliseconds period, bool listen = true);
  ~EventTail();  // stops
  EventTail(const EventTail&) = delete;
  EventTail& operator=(const EventTail&) = delete;

  // Primes the bus with the newest events held (up to `prime`) and starts polling.
  void start(std::size_t prime = 4096);
  void stop();  // idempotent; joins
  void wake();
  std::int64_t polls() const;  // for health: queries made
  // Notifications received (0 on SQLite or without `listen`).
  std::int64_t notifications() const;

 private:
  void loop();
  void listen_loop();  // wake() at each notification
  void poll();  // every event after last_, in pages

  storage::Historian h_;
  EventBus& bus_;
  const std::chrono::milliseconds period_;
  std::int64_t last_ = 0;  // the newest seq published
  mutable std::mutex mu_;  // guards woken_, stopping_, polls_
  std::condition_variable cv_;
  bool woken_ = false, stopping_ = false;
  std::int64_t polls_ = 0;
  std::thread thread_;
  std::unique_ptr<storage::EventListener> listener_;  // null: poll only
  std::thread listen_thread_;
};

Event to_event(const storage::StoredEvent& e);

// The events table as an EventBus::History, read through the REST
// server's readers: the events after an id, or nullopt when the id is not
// one of the table's (beyond its sequence) or events after it were pruned.
EventBus::History events_table_history(ReaderPool& pool);

}  // namespace ambdiag::server::detail
