#include "events/event_tail.h"

#include <algorithm>
#include <cstdio>

namespace ambdiag::server::detail {

Event to_event(const storage::StoredEvent& e) { return {static_cast<std::uint64_t>(e.seq), e.type, e.data_json}; }

EventBus::History events_table_history(ReaderPool& pool) {
  return [&pool](std::uint64_t after, std::size_t max) -> std::optional<std::vector<Event>> {
    auto h = pool.acquire();
    auto snap = h->snapshot();  // the bounds and the events of one state
    const auto last = h->last_event_seq();
    const auto first = h->first_event_seq();
    const auto after_seq = static_cast<std::int64_t>(after);
    // Below the first event held: pruned, unless the id is 0 (a client that
    // saw none wants all that is held; the first event's seq need not be 1:
    // on PostgreSQL a rolled-back insert, e.g. a killed holder's, leaves its
    // seq unused, and a server whose ring started later answered "reload").
    if (after_seq > last || (first ? after_seq != 0 && after_seq + 1 < *first : after_seq < last)) return std::nullopt;
    std::vector<Event> out;
    for (const auto& e : h->events_after(after_seq, static_cast<int>(std::min<std::size_t>(max, 1u << 30))))
      out.push_back(to_event(e));
    return out;
  };
}

EventTail::EventTail(const std::string& db_path, EventBus& bus, std::chrono::milliseconds period, bool listen)
    : h_(storage::Historian::open(db_path, storage::Historian::Mode::read)),
      bus_(bus),
      period_(std::max(period, std::chrono::milliseconds(1))),
      // LISTENing before start() reads where to go on from: an event
      // committed in between is announced, not left to the next period.
      listener_(listen ? storage::EventListener::open(db_path) : nullptr) {}

EventTail::~EventTail() { stop(); }

void EventTail::start(std::size_t prime) {
  if (thread_.joinable()) return;
  {
    // One snapshot: the ring's events and where the tail goes on from.
    auto snap = h_.snapshot();
    const auto recent = h_.recent_events(static_cast<int>(std::max<std::size_t>(1, prime)));
    last_ = h_.last_event_seq();
    bus_.start_at(static_cast<std::uint64_t>(recent.empty() ? last_ : recent.front().seq - 1));
    for (const auto& e : recent) bus_.publish_stored(to_event(e));
  }
  thread_ = std::thread([this] { loop(); });
  if (listener_) listen_thread_ = std::thread([this] { listen_loop(); });
}

void EventTail::stop() {
  {
    std::lock_guard l(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (listener_) listener_->interrupt();
  if (listen_thread_.joinable()) listen_thread_.join();
  if (thread_.joinable()) thread_.join();
}

void EventTail::wake() {
  {
    std::lock_guard l(mu_);
    woken_ = true;
  }
  cv_.notify_all();
}

std::int64_t EventTail::polls() const {
  std::lock_guard l(mu_);
  return polls_;
}

std::int64_t EventTail::notifications() const { return listener_ ? listener_->notifications() : 0; }

void EventTail::listen_loop() {
  for (;;) {
    {
      std::lock_guard l(mu_);
      if (stopping_) return;
    }
    // Bounded, so that a stop() between the check and the wait is seen.
    if (listener_->wait(std::chrono::seconds(1))) wake();
  }
}

void EventTail::loop() {
  std::unique_lock l(mu_);
  while (!stopping_) {
    cv_.wait_for(l, period_, [&] { return stopping_ || woken_; });
    if (stopping_) break;
    woken_ = false;
    ++polls_;
    l.unlock();
    try {
      poll();
    } catch (const std::exception& e) {  // the next period tries again
      std::fprintf(stderr, "ambdiag serve: events: %s\n", e.what());
    }
    l.lock();
  }
}

void EventTail::poll() {
  constexpr int kPage = 1000;
  for (;;) {
    const auto events = h_.events_after(last_, kPage);
    for (const auto& e : events) bus_.publish_stored(to_event(e));
    if (!events.empty()) last_ = events.back().seq;
    if (static_cast<int>(events.size()) < kPage) return;
  }
}

}  // namespace ambdiag::server::detail
