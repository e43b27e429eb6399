#include "ambdiag/server/events.h"

#include <algorithm>
#include <stdexcept>

namespace ambdiag::server {

struct EventBus::Subscription::Queue {
  std::mutex mu;
  std::condition_variable cv;
  std::deque<Event> events;
  std::size_t max = 0;
  std::uint64_t after = 0;  // what it was given at subscribe: later events only
  bool dropped = false, closed = false;
};

EventBus::EventBus(std::size_t ring_capacity)
    : capacity_(std::max<std::size_t>(1, ring_capacity)),
      next_id_(static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(
                                              std::chrono::system_clock::now().time_since_epoch())
                                              .count())) {}

EventBus::~EventBus() { close(); }

std::uint64_t EventBus::publish(const std::string& type, const nlohmann::json& data) {
  // The type is a field line of the stream: a newline would forge fields.
  if (type.empty() || type.find_first_of("\r\n") != std::string::npos)
    throw std::logic_error("event type must be one non-empty line");
  Event e{0, type, event_data(data)};
  std::lock_guard l(mu_);
  e.id = next_id_++;
  deliver(e);
  return e.id;
}

void EventBus::publish_stored(Event e) {
  std::lock_guard l(mu_);
  if (e.id < next_id_) return;  // held already (the tail read it twice) or older than where the bus started
  next_id_ = e.id + 1;
  deliver(e);
}

void EventBus::start_at(std::uint64_t id) {
  std::lock_guard l(mu_);
  if (!ring_.empty()) throw std::logic_error("EventBus::start_at after events were published");
  next_id_ = id + 1;
}

void EventBus::set_history(History history, std::size_t max_replay) {
  std::lock_guard l(mu_);
  history_ = std::move(history);
  max_replay_ = std::max<std::size_t>(1, max_replay);
}

void EventBus::deliver(const Event& e) {
  ring_.push_back(e);
  if (ring_.size() > capacity_) ring_.pop_front();
  for (const auto& q : subs_) {
    std::lock_guard ql(q->mu);
    if (q->dropped || q->closed || e.id <= q->after) continue;
    if (q->events.size() >= q->max) {
      q->dropped = true;  // a slow or dead client: its stream ends, the publisher goes on
      q->events.clear();
      ++dropped_;
    } else {
      q->events.push_back(e);
    }
    q->cv.notify_all();
  }
}

std::unique_ptr<EventBus::Subscription> EventBus::subscribe(std::optional<std::uint64_t> last_id,
                                                            std::size_t max_queue) {
  auto q = std::make_shared<Subscription::Queue>();
  q->max = std::max<std::size_t>(1, max_queue);
  std::unique_lock l(mu_);
  q->closed = closed_;
  const auto oldest_held = [&] { return ring_.empty() ? next_id_ : ring_.front().id; };
  // Replays what the ring holds after `after`; later events come as they are published.
  const auto replay_ring = [&](std::uint64_t after) {
    for (const auto& e : ring_)
      if (e.id > after) q->events.push_back(e);
    q->after = std::max(after, next_id_ - 1);
  };
  if (last_id) {
    if (*last_id < next_id_ && *last_id + 1 >= oldest_held()) {
      replay_ring(*last_id);
    } else {
      // Older than the ring, or ahead of it (another server's tail was
      // quicker): the history says whether the id is one of its own.
      std::optional<std::vector<Event>> older;
      if (const auto history = history_) {
        l.unlock();
        older = history(*last_id, max_replay_);
        l.lock();
      }
      const std::uint64_t upto = older && !older->empty() ? older->back().id : *last_id;
      // A history shorter than its maximum reaches the present; a full one must reach the ring.
      if (older && (older->size() < max_replay_ || upto + 1 >= oldest_held())) {
        q->events.assign(older->begin(), older->end());
        replay_ring(upto);
        q->after = std::max(q->after, upto);
      } else {
        const std::uint64_t newest = next_id_ - 1;
        const nlohmann::json d = {
            {"reason", *last_id > newest
                           ? "Last-Event-ID " + std::to_string(*last_id) + " is not of this server's events"
                           : "events after " + std::to_string(*last_id) + " are no longer held"},
            {"last_event_id", newest}};
        q->events.push_back({newest, "reload", d.dump()});
        q->after = newest;
      }
    }
  } else {
    q->after = next_id_ - 1;
  }
  subs_.push_back(q);
  return std::unique_ptr<Subscription>(new Subscription(*this, q));
}

void EventBus::close() {
  std::lock_guard l(mu_);
  closed_ = true;
  for (const auto& q : subs_) {
    std::lock_guard ql(q->mu);
    q->closed = true;
    q->cv.notify_all();
  }
}

std::uint64_t EventBus::last_id() const {
  std::lock_guard l(mu_);
  return next_id_ - 1;
}

std::size_t EventBus::subscribers() const {
  std::lock_guard l(mu_);
  return subs_.size();
}

std::uint64_t EventBus::dropped_total() const {
  std::lock_guard l(mu_);
  return dropped_;
}

EventBus::Subscription::~Subscription() {
  std::lock_guard l(bus_.mu_);
  bus_.subs_.erase(std::remove(bus_.subs_.begin(), bus_.subs_.end(), q_), bus_.subs_.end());
}

std::vector<Event> EventBus::Subscription::wait(std::chrono::milliseconds timeout) {
  std::unique_lock l(q_->mu);
  q_->cv.wait_for(l, timeout, [&] { return !q_->events.empty() || q_->dropped || q_->closed; });
  if (q_->dropped || q_->closed) return {};
  std::vector<Event> out(std::make_move_iterator(q_->events.begin()),
                         std::make_move_iterator(q_->events.end()));
  q_->events.clear();
  return out;
}

bool EventBus::Subscription::ended() const {
  std::lock_guard l(q_->mu);
  return q_->dropped || q_->closed;
}

bool EventBus::Subscription::dropped() const {
  std::lock_guard l(q_->mu);
  return q_->dropped;
}

std::string sse_frame(const Event& e) {
  // The type and data hold no newline (a type is ours, data is one line of
  // JSON, whose strings escape newlines), so each is one field line.
  return "id: " + std::to_string(e.id) + "\nevent: " + e.type + "\ndata: " + e.data + "\n\n";
}

std::string event_data(const nlohmann::json& data) {
  return data.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace ambdiag::server
