// A wake-up for the readers of the events table (events.h) on PostgreSQL:
// append_event also NOTIFYs, delivered when its transaction commits, and an
// EventListener holds one connection LISTENing for those notifications, so
// a REST process' tail reads a new event within milliseconds of its commit
// on any server instead of at its next poll (docs/service.md "Several
// servers"). The poll stays: a notification can be lost with the
// connection, and the reader catches up by seq after a reconnect.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

namespace ambdiag::storage {

class EventListener {
 public:
  // nullptr for an SQLite location (no notifications there: the readers
  // poll). For PostgreSQL, connects and LISTENs; a server that cannot be
  // reached now is tried again at each wait() (at most once a second).
  static std::unique_ptr<EventListener> open(const std::string& location);
  ~EventListener();
  EventListener(const EventListener&) = delete;
  EventListener& operator=(const EventListener&) = delete;

  // Waits up to `timeout` for a notification. true: one or more events
  // were committed, or the connection was (re)made and what was committed
  // meanwhile went unannounced: the caller reads after its last seq. false:
  // the timeout, an interrupt(), or the connection lost (tried again later).
  bool wait(std::chrono::milliseconds timeout);
  // Makes a wait() in another thread return at once (false).
  void interrupt();

  std::int64_t notifications() const;  // received so far (each commit's, maybe merged)
  std::int64_t reconnects() const;     // connections made after a loss
  bool connected() const;

  struct State;

 private:
  explicit EventListener(std::unique_ptr<State> s);
  std::unique_ptr<State> s_;
};

}  // namespace ambdiag::storage
