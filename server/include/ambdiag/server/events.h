// The in-process event bus behind GET /api/v1/events (server-sent events;
// docs/service.md "Live updates"). Ingest, the analysis service and (later)
// the alarms publish; each open stream subscribes.
//
// Every event has an id, a type ("run.new", "run.status", "job.done", ...)
// and a JSON object. Ids increase by one per event and start at the wall
// clock's microseconds when the bus is made, so they keep increasing across
// a server restart: a client's Last-Event-ID from an earlier process is
// older than anything held and it is told to reload.
//
// The last `ring_capacity` events are kept: a subscriber that names the id
// it saw last gets the ones after it that are still held, or, when some
// are gone, first a "reload" event (its id is the newest id, so a client
// that reloads and keeps that id misses nothing after it).
//
// publish never waits for a subscriber: each has a bounded queue, and one
// whose queue is full is dropped (its stream ends; the client reconnects
// with its Last-Event-ID and gets what is still in the ring).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::server {

struct Event {
  std::uint64_t id = 0;
  std::string type;
  std::string data;  // a JSON object on one line
};

class EventBus {
 public:
  explicit EventBus(std::size_t ring_capacity = 4096);
  ~EventBus();
  EventBus(const EventBus&) = delete;
  EventBus& operator=(const EventBus&) = delete;

  // Thread-safe; returns the event's id. `data` should be an object; a
  // type with a line break is a programming error (std::logic_error).
  std::uint64_t publish(const std::string& type, const nlohmann::json& data);

  class Subscription {
   public:
    ~Subscription();  // unsubscribes
    Subscription(const Subscription&) = delete;
    Subscription& operator=(const Subscription&) = delete;
    // The events queued for this subscriber, waiting up to `timeout` for the
    // first. Empty after the timeout, or when ended() (dropped or closed).
    std::vector<Event> wait(std::chrono::milliseconds timeout);
    // Dropped (its queue overflowed) or the bus was closed: stop streaming.
    bool ended() const;
    bool dropped() const;

   private:
    friend class EventBus;
    struct Queue;
    Subscription(EventBus& bus, std::shared_ptr<Queue> q) : bus_(bus), q_(std::move(q)) {}
    EventBus& bus_;
    std::shared_ptr<Queue> q_;
  };
  // `last_id`: the id the client saw last (Last-Event-ID), nullopt for a
  // new client (nothing replayed). `max_queue`: events held for it before
  // it is dropped.
  std::unique_ptr<Subscription> subscribe(std::optional<std::uint64_t> last_id, std::size_t max_queue = 1024);

  // Ends every subscription, now and later (the server stops).
  void close();
  std::uint64_t last_id() const;
  std::size_t subscribers() const;
  std::uint64_t dropped_total() const;

 private:
  mutable std::mutex mu_;
  std::size_t capacity_;
  std::uint64_t next_id_;
  std::deque<Event> ring_;
  std::vector<std::shared_ptr<Subscription::Queue>> subs_;
  bool closed_ = false;
  std::uint64_t dropped_ = 0;
};

// The text/event-stream form of one event: "id: N\nevent: TYPE\ndata: JSON\n\n".
std::string sse_frame(const Event& e);

}  // namespace ambdiag::server
