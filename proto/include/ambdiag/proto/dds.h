// A small C++ layer over the Cyclone DDS C API (Debian ships no C++ binding).
//
// Every DDS entity lives in a move-only owner that deletes it; every
// dds_return_t goes through check(), which throws DdsError naming the call.
// Samples are the C structs idlc generates from proto/idl/ambdiag_stream.idl.
#pragma once

#include <dds/dds.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace ambdiag::dds {

// A failed DDS call: what() is "CALL: message (code)".
class DdsError : public std::runtime_error {
 public:
  DdsError(const std::string& call, dds_return_t code);
  dds_return_t code() const { return code_; }

 private:
  dds_return_t code_;
};

// The one place return codes are checked: returns rc if >= 0, else throws.
dds_return_t check(dds_return_t rc, const char* call);

inline dds_duration_t to_dds(std::chrono::nanoseconds d) { return static_cast<dds_duration_t>(d.count()); }

// Owns a dds_entity_t and deletes it (and its children) on destruction.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  Entity(Entity&& o) noexcept : handle_(std::exchange(o.handle_, 0)) {}
  Entity& operator=(Entity&& o) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  ~Entity();
  dds_entity_t get() const { return handle_; }
  explicit operator bool() const { return handle_ > 0; }

 private:
  dds_entity_t handle_ = 0;
};

// QoS builder; owns the dds_qos_t.
class Qos {
 public:
  Qos();
  Qos(Qos&& o) noexcept : q_(std::exchange(o.q_, nullptr)) {}
  Qos& operator=(Qos&&) = delete;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;
  ~Qos();
  Qos& reliable(std::chrono::nanoseconds max_blocking = std::chrono::seconds(1));
  Qos& best_effort();
  Qos& keep_all();
  Qos& keep_last(int32_t depth);
  Qos& resource_limits(int32_t max_samples, int32_t max_instances, int32_t max_samples_per_instance);
  Qos& transient_local();
  Qos& partitions(const std::vector<std::string>& names);
  Qos& liveliness_automatic(std::chrono::nanoseconds lease);
  const dds_qos_t* get() const { return q_; }

 private:
  dds_qos_t* q_;
};

class Participant : public Entity {
 public:
  explicit Participant(dds_domainid_t domain);
};

class Topic : public Entity {
 public:
  Topic(const Participant& p, const dds_topic_descriptor_t* type, const std::string& name);
};

class Publisher : public Entity {
 public:
  Publisher(const Participant& p, const Qos& qos);
};

class Subscriber : public Entity {
 public:
  Subscriber(const Participant& p, const Qos& qos);
};

// A writer of the idlc-generated C struct T.
template <class T>
class Writer : public Entity {
 public:
  Writer(const Publisher& pub, const Topic& topic, const Qos& qos)
      : Entity(check(dds_create_writer(pub.get(), topic.get(), qos.get(), nullptr), "dds_create_writer")) {}
  // False if the reader side pushed back for longer than max_blocking
  // (DDS_RETCODE_TIMEOUT); the caller keeps the sample and tries again.
  bool write(const T& sample) const { return write_raw(&sample); }
  void unregister(const T& sample) const;
  // Number of matched readers right now.
  int32_t matched() const;
  // True once every matched reader acknowledged everything written.
  bool wait_for_acks(std::chrono::nanoseconds timeout) const;

 private:
  bool write_raw(const void* sample) const;
};

// A reader of T; take() hands loaned samples to a callback and returns them.
template <class T>
class Reader : public Entity {
 public:
  Reader(const Subscriber& sub, const Topic& topic, const Qos& qos)
      : Entity(check(dds_create_reader(sub.get(), topic.get(), qos.get(), nullptr), "dds_create_reader")) {}
  // Takes up to max_n samples; calls on_sample for each valid one (not for
  // instance state changes without data). Returns the number of valid ones.
  size_t take(size_t max_n, const std::function<void(const T&, const dds_sample_info_t&)>& on_sample) const {
    return take_raw(max_n, [&](const void* s, const dds_sample_info_t& i) { on_sample(*static_cast<const T*>(s), i); });
  }
  // Number of matched writers right now.
  int32_t matched() const;
  // Samples refused so far because the reader's resource limits were full
  // (reliable writers re-send them: back-pressure that costs round trips).
  int64_t rejected_total() const;

 private:
  size_t take_raw(size_t max_n, const std::function<void(const void*, const dds_sample_info_t&)>& f) const;
};

// The partitions of the remote writer `writer` (a sample's
// publication_handle) matched with `reader`; nothing if it is no longer
// matched (gone before its sample was taken).
std::optional<std::vector<std::string>> matched_writer_partitions(const Entity& reader, dds_instance_handle_t writer);

// Waits until any attached reader has data (or the timeout passes).
class WaitSet : public Entity {
 public:
  explicit WaitSet(const Participant& p);
  // Attaches a read condition on `reader` for any unread sample.
  void attach_data(const Entity& reader);
  // Returns the number of triggered conditions (0 on timeout).
  int wait(std::chrono::nanoseconds timeout);
  // Wakes a waiting thread (e.g. on shutdown).
  void trigger();

 private:
  std::vector<Entity> conditions_;
  Entity guard_;
};

}  // namespace ambdiag::dds
