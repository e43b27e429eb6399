#include "ambdiag/proto/stream.h"

#include <chrono>

namespace ambdiag::stream {

using namespace std::chrono_literals;

std::string version_string(uint32_t v) {
  return std::to_string(protocol_major(v)) + "." + std::to_string(protocol_minor(v));
}

std::optional<uint32_t> minor_of(const std::string& version) {
  for (uint32_t m = 0; m <= ambdiag_stream_kProtocolMinor; ++m)
    if (version == version_string(protocol_version(m))) return m;
  return std::nullopt;
}

namespace {
std::string data_topic(const char* name) {
  return "ambdiag_v" + std::to_string(ambdiag_stream_kProtocolMajor) + "_" + name;
}
}  // namespace

Topics::Topics(const dds::Participant& p)
    : header(p, &ambdiag_stream_RunHeader_desc, data_topic("RunHeader")),
      block(p, &ambdiag_stream_SampleBlock_desc, data_topic("SampleBlock")),
      end(p, &ambdiag_stream_RunEnd_desc, data_topic("RunEnd")),
      ack(p, &ambdiag_stream_Ack_desc, "ambdiag_Ack"),
      status(p, &ambdiag_stream_AgentStatus_desc, "ambdiag_AgentStatus"),
      monitoring(p, &ambdiag_stream_MonitoringSnapshot_desc, data_topic("MonitoringSnapshot")) {}

dds::Qos block_writer_qos() {
  dds::Qos q;
  // The writer blocks at most 100 ms when readers push back; the agent keeps
  // the block in its spool and retries, so a slow server never stalls it long.
  q.reliable(100ms).keep_all().resource_limits(kBlockReaderMaxSamples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  return q;
}
dds::Qos block_reader_qos() {
  dds::Qos q;
  q.reliable().keep_all().resource_limits(kBlockReaderMaxSamples, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  return q;
}
dds::Qos control_qos() {
  dds::Qos q;
  q.reliable().transient_local().keep_last(1).resource_limits(4096, 4096, 1);
  return q;
}
dds::Qos ack_qos() {
  dds::Qos q;
  q.reliable(100ms).keep_all().resource_limits(4096, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  return q;
}
dds::Qos status_qos() {
  dds::Qos q;
  q.reliable().keep_last(1).resource_limits(4096, 4096, 1);
  return q;
}
dds::Qos monitoring_qos() {
  dds::Qos q;
  q.reliable().keep_last(16);
  return q;
}

namespace {
dds::Qos partition_qos(const std::vector<std::string>& names) {
  dds::Qos q;
  q.partitions(names);
  return q;
}
}  // namespace

AgentEndpoints::AgentEndpoints(dds_domainid_t domain, const std::string& partition)
    : participant(domain),
      topics(participant),
      publisher(participant, partition_qos({partition})),
      subscriber(participant, partition_qos({partition})),
      header(publisher, topics.header, control_qos()),
      block(publisher, topics.block, block_writer_qos()),
      end(publisher, topics.end, control_qos()),
      status(publisher, topics.status, status_qos()),
      monitoring(publisher, topics.monitoring, monitoring_qos()),
      ack(subscriber, topics.ack, ack_qos()) {}

ServerEndpoints::ServerEndpoints(dds_domainid_t domain, const std::vector<std::string>& partitions)
    : participant(domain),
      topics(participant),
      publisher(participant, partition_qos(partitions)),
      subscriber(participant, partition_qos(partitions)),
      header(subscriber, topics.header, control_qos()),
      block(subscriber, topics.block, block_reader_qos()),
      end(subscriber, topics.end, control_qos()),
      status(subscriber, topics.status, status_qos()),
      monitoring(subscriber, topics.monitoring, monitoring_qos()),
      ack(publisher, topics.ack, ack_qos()) {}

bool plain_partition_name(const std::string& name) {
  return !name.empty() && name.find_first_of("/*?[]\\") == std::string::npos;
}

std::string pump_partition(const std::string& site, const std::string& pump) { return site + "/" + pump; }

std::optional<std::string> pump_of_partitions(const std::vector<std::string>& partitions) {
  if (partitions.size() != 1) return std::nullopt;
  const auto slash = partitions[0].find('/');
  if (slash == std::string::npos || slash + 1 == partitions[0].size()) return std::nullopt;
  return partitions[0].substr(slash + 1);
}

dds_sequence_octet borrow_octets(const void* data, size_t n) {
  dds_sequence_octet s{};
  s._maximum = static_cast<uint32_t>(n);
  s._length = static_cast<uint32_t>(n);
  s._buffer = static_cast<uint8_t*>(const_cast<void*>(data));
  s._release = false;
  return s;
}

}  // namespace ambdiag::stream
