// The event bus behind GET /api/v1/events (server-sent events;
// docs/service.md "Live updates"): each open stream subscribes.
//
// Every event has an id, a type ("run.new", "run.status", "job.done", ...)
// and a JSON object. In a server the events come from the historian's
// events table (EventTail, event_tail.h, publishes them with publish_stored):
// the ids are the table's seqs, the same on every server on the database.
// Published here directly (publish), ids increase by one per event and
// start at the wall clock's microseconds when the bus is made.
//
// The last `ring_capacity` events are kept: a subscriber that names the id
// it saw last gets the ones after it that are still held, in the ring or,
// older, from the history (set_history: the table), or, when some are gone,
// first a "reload" event (its id is the newest id, so a client that reloads
// and keeps that id misses nothing after it).
//
// publish never waits for a subscriber: each has a bounded queue, and one
// whose queue is full is dropped (its stream ends; the client reconnects
// with its Last-Event-ID and gets what is still in the ring).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
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
  // An event with its own id (a stored event's seq); ignored unless its id
  // is above last_id(). Ids may jump (pruned or rolled-back seqs).
  void publish_stored(Event e);
  // Where the ids go on from: last_id() becomes `id` (only while nothing
  // was published; std::logic_error otherwise). The tail sets the table's
  // sequence before its first event.
  void start_at(std::uint64_t id);
  // The events after `after_id` that are older than the ring, read from
  // where they are kept (the events table), oldest first, at most `max`;
  // nullopt when `after_id` is not a point of that history (events after it
  // pruned, or an id beyond its newest). Called without the bus' lock, from
  // the subscribing thread.
  using History = std::function<std::optional<std::vector<Event>>(std::uint64_t after_id, std::size_t max)>;
  void set_history(History history, std::size_t max_replay = 10000);

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
  void deliver(const Event& e);  // to every subscriber; mu_ held

  mutable std::mutex mu_;
  History history_;
  std::size_t max_replay_ = 0;
  std::size_t capacity_;
  std::uint64_t next_id_;
  std::deque<Event> ring_;
  std::vector<std::shared_ptr<Subscription::Queue>> subs_;
  bool closed_ = false;
  std::uint64_t dropped_ = 0;
};

// The text/event-stream form of one event: "id: N\nevent: TYPE\ndata: JSON\n\n".
std::string sse_frame(const Event& e);

// An event's data as stored and sent: one line of JSON, invalid UTF-8 (in
// a message from a file or an exception) replaced rather than refused.
std::string event_data(const nlohmann::json& data);

}  // namespace ambdiag::server
