#include "ambdiag/proto/dds.h"

#include <array>

#include "ambdiag_stream.h"

namespace ambdiag::dds {

DdsError::DdsError(const std::string& call, dds_return_t code)
    : std::runtime_error(call + ": " + dds_strretcode(code) + " (" + std::to_string(code) + ")"), code_(code) {}

dds_return_t check(dds_return_t rc, const char* call) {
  if (rc < 0) throw DdsError(call, rc);
  return rc;
}

Entity& Entity::operator=(Entity&& o) noexcept {
  if (this != &o) {
    if (handle_ > 0) dds_delete(handle_);
    handle_ = std::exchange(o.handle_, 0);
  }
  return *this;
}

Entity::~Entity() {
  // A child already deleted with its parent returns an error: nothing to do.
  if (handle_ > 0) dds_delete(handle_);
}

Qos::Qos() : q_(dds_create_qos()) {}
Qos::~Qos() {
  if (q_) dds_delete_qos(q_);
}
Qos& Qos::reliable(std::chrono::nanoseconds max_blocking) {
  dds_qset_reliability(q_, DDS_RELIABILITY_RELIABLE, to_dds(max_blocking));
  return *this;
}
Qos& Qos::best_effort() {
  dds_qset_reliability(q_, DDS_RELIABILITY_BEST_EFFORT, 0);
  return *this;
}
Qos& Qos::keep_all() {
  dds_qset_history(q_, DDS_HISTORY_KEEP_ALL, 0);
  return *this;
}
Qos& Qos::keep_last(int32_t depth) {
  dds_qset_history(q_, DDS_HISTORY_KEEP_LAST, depth);
  return *this;
}
Qos& Qos::resource_limits(int32_t max_samples, int32_t max_instances, int32_t max_samples_per_instance) {
  dds_qset_resource_limits(q_, max_samples, max_instances, max_samples_per_instance);
  return *this;
}
Qos& Qos::transient_local() {
  dds_qset_durability(q_, DDS_DURABILITY_TRANSIENT_LOCAL);
  return *this;
}
Qos& Qos::partitions(const std::vector<std::string>& names) {
  std::vector<const char*> ps;
  for (const auto& n : names) ps.push_back(n.c_str());
  dds_qset_partition(q_, static_cast<uint32_t>(ps.size()), ps.data());
  return *this;
}
Qos& Qos::liveliness_automatic(std::chrono::nanoseconds lease) {
  dds_qset_liveliness(q_, DDS_LIVELINESS_AUTOMATIC, to_dds(lease));
  return *this;
}

Participant::Participant(dds_domainid_t domain)
    : Entity(check(dds_create_participant(domain, nullptr, nullptr), "dds_create_participant")) {}

std::optional<std::vector<std::string>> matched_writer_partitions(const Entity& reader, dds_instance_handle_t writer) {
  dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(reader.get(), writer);
  if (!ep) return std::nullopt;
  std::vector<std::string> out;
  uint32_t n = 0;
  char** names = nullptr;
  if (ep->qos && dds_qget_partition(ep->qos, &n, &names)) {
    for (uint32_t i = 0; i < n; ++i) {
      out.emplace_back(names[i]);
      dds_free(names[i]);
    }
    dds_free(names);
  }
  dds_builtintopic_free_endpoint(ep);
  return out;
}

Topic::Topic(const Participant& p, const dds_topic_descriptor_t* type, const std::string& name)
    : Entity(check(dds_create_topic(p.get(), type, name.c_str(), nullptr, nullptr), "dds_create_topic")) {}

Publisher::Publisher(const Participant& p, const Qos& qos)
    : Entity(check(dds_create_publisher(p.get(), qos.get(), nullptr), "dds_create_publisher")) {}

Subscriber::Subscriber(const Participant& p, const Qos& qos)
    : Entity(check(dds_create_subscriber(p.get(), qos.get(), nullptr), "dds_create_subscriber")) {}

template <class T>
bool Writer<T>::write_raw(const void* sample) const {
  const dds_return_t rc = dds_write(get(), sample);
  if (rc == DDS_RETCODE_TIMEOUT) return false;
  check(rc, "dds_write");
  return true;
}

template <class T>
void Writer<T>::unregister(const T& sample) const {
  check(dds_unregister_instance(get(), &sample), "dds_unregister_instance");
}

template <class T>
int32_t Writer<T>::matched() const {
  dds_publication_matched_status_t st;
  check(dds_get_publication_matched_status(get(), &st), "dds_get_publication_matched_status");
  return static_cast<int32_t>(st.current_count);
}

template <class T>
bool Writer<T>::wait_for_acks(std::chrono::nanoseconds timeout) const {
  const dds_return_t rc = dds_wait_for_acks(get(), to_dds(timeout));
  if (rc == DDS_RETCODE_TIMEOUT) return false;
  check(rc, "dds_wait_for_acks");
  return true;
}

template <class T>
int32_t Reader<T>::matched() const {
  dds_subscription_matched_status_t st;
  check(dds_get_subscription_matched_status(get(), &st), "dds_get_subscription_matched_status");
  return static_cast<int32_t>(st.current_count);
}

template <class T>
int64_t Reader<T>::rejected_total() const {
  dds_sample_rejected_status_t st;
  check(dds_get_sample_rejected_status(get(), &st), "dds_get_sample_rejected_status");
  return st.total_count;
}

template <class T>
size_t Reader<T>::take_raw(size_t max_n, const std::function<void(const void*, const dds_sample_info_t&)>& f) const {
  constexpr size_t kBatch = 64;
  size_t valid = 0;
  while (max_n > 0) {
    std::array<void*, kBatch> buf{};
    std::array<dds_sample_info_t, kBatch> info{};
    const size_t want = std::min(max_n, kBatch);
    const dds_return_t n = check(dds_take(get(), buf.data(), info.data(), want, static_cast<uint32_t>(want)), "dds_take");
    struct Loan {  // returns the loan even if the callback throws
      dds_entity_t rd;
      void** b;
      int32_t n;
      ~Loan() {
        if (n > 0) dds_return_loan(rd, b, n);
      }
    } loan{get(), buf.data(), n};
    for (int32_t i = 0; i < n; ++i) {
      if (!info[static_cast<size_t>(i)].valid_data) continue;
      f(buf[static_cast<size_t>(i)], info[static_cast<size_t>(i)]);
      ++valid;
    }
    if (static_cast<size_t>(n) < want) break;
    max_n -= static_cast<size_t>(n);
  }
  return valid;
}

WaitSet::WaitSet(const Participant& p) : Entity(check(dds_create_waitset(p.get()), "dds_create_waitset")) {
  guard_ = Entity(check(dds_create_guardcondition(p.get()), "dds_create_guardcondition"));
  check(dds_waitset_attach(get(), guard_.get(), 0), "dds_waitset_attach");
}

void WaitSet::attach_data(const Entity& reader) {
  Entity cond(check(dds_create_readcondition(reader.get(), DDS_NOT_READ_SAMPLE_STATE | DDS_ANY_VIEW_STATE |
                                                               DDS_ANY_INSTANCE_STATE),
                    "dds_create_readcondition"));
  check(dds_waitset_attach(get(), cond.get(), static_cast<dds_attach_t>(conditions_.size() + 1)), "dds_waitset_attach");
  conditions_.push_back(std::move(cond));
}

int WaitSet::wait(std::chrono::nanoseconds timeout) {
  std::array<dds_attach_t, 16> xs{};
  const dds_return_t n = check(dds_waitset_wait(get(), xs.data(), xs.size(), to_dds(timeout)), "dds_waitset_wait");
  for (dds_return_t i = 0; i < std::min<dds_return_t>(n, static_cast<dds_return_t>(xs.size())); ++i) {
    if (xs[static_cast<size_t>(i)] == 0) check(dds_set_guardcondition(guard_.get(), false), "dds_set_guardcondition");
  }
  return n;
}

void WaitSet::trigger() { check(dds_set_guardcondition(guard_.get(), true), "dds_set_guardcondition"); }

// The sample types of the stream.
template class Writer<ambdiag_stream_RunHeader>;
template class Writer<ambdiag_stream_SampleBlock>;
template class Writer<ambdiag_stream_RunEnd>;
template class Writer<ambdiag_stream_Ack>;
template class Writer<ambdiag_stream_AgentStatus>;
template class Writer<ambdiag_stream_MonitoringSnapshot>;
template class Reader<ambdiag_stream_RunHeader>;
template class Reader<ambdiag_stream_SampleBlock>;
template class Reader<ambdiag_stream_RunEnd>;
template class Reader<ambdiag_stream_Ack>;
template class Reader<ambdiag_stream_AgentStatus>;
template class Reader<ambdiag_stream_MonitoringSnapshot>;

}  // namespace ambdiag::dds
