// EventListener (event_listener.h): one PostgreSQL connection that LISTENs
// on the historian's events channel, waited on with poll() beside a pipe
// that interrupt() writes to.
#include "ambdiag/storage/event_listener.h"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "events_channel.h"
#include "sql/postgres/pg_db.h"

namespace ambdiag::storage {

using Clock = std::chrono::steady_clock;

struct EventListener::State {
  std::string location;
  std::unique_ptr<detail::PgDb> db;  // null while disconnected
  int pipe_fds[2] = {-1, -1};        // interrupt(): [1] written, [0] polled
  Clock::time_point next_connect{};
  bool ever_connected = false;
  std::atomic<std::int64_t> notifications{0}, reconnects{0};
  std::atomic<bool> up{false};

  ~State() {
    for (int fd : pipe_fds)
      if (fd >= 0) ::close(fd);
  }

  // Connects and LISTENs; on failure says why once per outage and tries
  // again a second later. true: connected now.
  bool connect() {
    next_connect = Clock::now() + std::chrono::seconds(1);
    try {
      auto c = detail::PgDb::open(location, true);
      c->exec("DO $$ BEGIN EXECUTE 'LISTEN ' || quote_ident(" AMBDIAG_EVENTS_CHANNEL_SQL "); END $$",
              "LISTEN on the events channel");
      db = std::move(c);
    } catch (const std::exception& e) {
      if (up.exchange(false) || !ever_connected)
        std::fprintf(stderr, "ambdiag: events: no notifications (%s); polling until PostgreSQL is back\n", e.what());
      ever_connected = true;  // one message per outage
      return false;
    }
    if (ever_connected) ++reconnects;
    ever_connected = true;
    up = true;
    return true;
  }

  void lose(std::string why) {
    for (char& c : why)
      if (c == '\n' || c == '\t') c = ' ';  // libpq's message is several lines
    while (!why.empty() && why.back() == ' ') why.pop_back();
    std::fprintf(stderr, "ambdiag: events: the notification connection was lost (%s); polling until it is back\n",
                 why.c_str());
    db.reset();
    up = false;
    next_connect = Clock::now() + std::chrono::milliseconds(200);  // a restart takes a moment
  }

  // Reads the notifications that arrived; count of them.
  int drain() {
    int n = 0;
    while (PGnotify* note = PQnotifies(db->get())) {
      PQfreemem(note);
      ++n;
    }
    notifications += n;
    return n;
  }

  void drain_pipe() {
    char buf[64];
    while (::read(pipe_fds[0], buf, sizeof buf) > 0) {
    }
  }
};

std::unique_ptr<EventListener> EventListener::open(const std::string& location) {
  if (!is_postgres_location(location)) return nullptr;
  auto s = std::make_unique<State>();
  s->location = location;
  if (::pipe2(s->pipe_fds, O_NONBLOCK | O_CLOEXEC) != 0) throw StorageError("EventListener: cannot make a pipe");
  s->connect();
  return std::unique_ptr<EventListener>(new EventListener(std::move(s)));
}

EventListener::EventListener(std::unique_ptr<State> s) : s_(std::move(s)) {}
EventListener::~EventListener() = default;

bool EventListener::wait(std::chrono::milliseconds timeout) {
  auto& s = *s_;
  const auto deadline = Clock::now() + timeout;
  if (!s.db && Clock::now() >= s.next_connect && s.connect()) return true;  // catch up what went unannounced
  if (s.db && s.drain() > 0) return true;
  const auto until = s.db ? deadline : std::min(deadline, s.next_connect);
  const auto ms = std::chrono::ceil<std::chrono::milliseconds>(until - Clock::now()).count();
  pollfd fds[2] = {{s.pipe_fds[0], POLLIN, 0}, {s.db ? PQsocket(s.db->get()) : -1, POLLIN, 0}};
  const int r = ::poll(fds, 2, static_cast<int>(std::max<long long>(0, ms)));
  if (r <= 0) return false;
  if (fds[0].revents) {
    s.drain_pipe();
    return false;
  }
  if (s.db && fds[1].revents) {
    if (!PQconsumeInput(s.db->get()) || PQstatus(s.db->get()) != CONNECTION_OK) {
      s.lose(PQerrorMessage(s.db->get()));
      return false;
    }
    return s.drain() > 0;
  }
  return false;
}

void EventListener::interrupt() {
  const char b = 1;
  [[maybe_unused]] const auto n = ::write(s_->pipe_fds[1], &b, 1);  // full pipe: a wake-up is pending anyway
}

std::int64_t EventListener::notifications() const { return s_->notifications; }
std::int64_t EventListener::reconnects() const { return s_->reconnects; }
bool EventListener::connected() const { return s_->up; }

}  // namespace ambdiag::storage
