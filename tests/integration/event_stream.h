// GET /api/v1/events read by a real client on its own thread, as a
// browser's EventSource would (the token in the query): the integration
// tests wait for the events the server publishes.
#pragma once

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::testing {

using namespace std::chrono_literals;

// One event as a client saw it.
struct SeenEvent {
  std::string id, type;
  nlohmann::json data;
  std::chrono::steady_clock::time_point at;  // when the client parsed it
};

// The events a stream delivers, parsed, read on their own thread; with a
// `last_event_id`, a reconnecting client (the Last-Event-ID header).
class EventStream {
 public:
  EventStream(int port, const std::string& token, const std::string& last_event_id = "") : client_("127.0.0.1", port) {
    thread_ = std::thread([this, token, last_event_id] {
      auto& c = client_;
      c.set_read_timeout(30, 0);
      std::string pending;
      httplib::Headers headers;
      if (!last_event_id.empty()) headers.emplace("Last-Event-ID", last_event_id);
      c.Get(
          "/api/v1/events?access_token=" + token, headers,
          [&](const httplib::Response& r) {
            connected_ = r.status == 200;
            return true;
          },
          [&](const char* d, size_t n) {
            pending.append(d, n);
            for (size_t end; (end = pending.find("\n\n")) != std::string::npos; pending.erase(0, end + 2)) {
              std::smatch m;
              const std::string frame = pending.substr(0, end + 1);
              if (std::regex_search(frame, m, std::regex("id: (.*)\nevent: (.*)\ndata: (.*)\n"))) {
                std::lock_guard l(mu_);
                events_.push_back({m[1], m[2], nlohmann::json::parse(m[3].str()), std::chrono::steady_clock::now()});
              }
            }
            return !stop_;
          });
    });
  }
  bool wait_connected() {
    for (int i = 0; i < 500 && !connected_; ++i) std::this_thread::sleep_for(10ms);
    return connected_;
  }
  ~EventStream() {
    stop_ = true;
    client_.stop();  // now, not at the next heartbeat
    thread_.join();
  }
  // The first event of `type` whose data holds `key` == `value`.
  std::optional<nlohmann::json> wait_for(const std::string& type, const std::string& key,
                                         const std::string& value, std::chrono::seconds timeout = 120s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      {
        std::lock_guard l(mu_);
        for (const auto& e : events_)
          if (e.type == type && e.data.value(key, nlohmann::json()).is_string() && e.data[key] == value) return e.data;
      }
      std::this_thread::sleep_for(50ms);
    }
    return std::nullopt;
  }
  std::string seen() {
    std::lock_guard l(mu_);
    std::string s;
    for (const auto& e : events_) s += e.id + " " + e.type + " " + e.data.dump() + "\n";
    return s;
  }
  std::vector<SeenEvent> events() {
    std::lock_guard l(mu_);
    return events_;
  }

 private:
  httplib::Client client_;
  std::thread thread_;
  std::mutex mu_;
  std::vector<SeenEvent> events_;
  std::atomic<bool> stop_{false}, connected_{false};
};

}  // namespace ambdiag::testing
