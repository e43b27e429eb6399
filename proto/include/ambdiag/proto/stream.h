// The stream's topics, QoS and protocol rules, shared by agent and server
// (docs/streaming.md explains each choice).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ambdiag/proto/dds.h"
#include "ambdiag_stream.h"

namespace ambdiag::stream {

// protocol_version = (major << 16) | minor; same major = compatible.
inline constexpr uint32_t kProtocolVersion = (ambdiag_stream_kProtocolMajor << 16) | ambdiag_stream_kProtocolMinor;
inline constexpr uint32_t protocol_major(uint32_t v) { return v >> 16; }
inline constexpr uint32_t protocol_minor(uint32_t v) { return v & 0xffffu; }
inline constexpr bool compatible(uint32_t v) { return protocol_major(v) == ambdiag_stream_kProtocolMajor; }
std::string version_string(uint32_t v);  // "1.0"
// 1.2: the server acknowledges blocks and verdicts as durable (Ack::durable).
inline constexpr uint32_t kDurableAckMinor = 2;
inline constexpr uint32_t protocol_version(uint32_t minor) { return (ambdiag_stream_kProtocolMajor << 16) | minor; }
// "1.1" -> its minor, for processes told to speak an older minor (the
// version tests); nothing for another major or a minor this build does not know.
std::optional<uint32_t> minor_of(const std::string& version);

// Readers refuse blocks larger than this (a 15-channel block of 512 frames
// is 30 KiB; 4 MiB leaves room for 8 kHz x 64 channels x 2 s).
inline constexpr uint32_t kMaxBlockPayloadBytes = 4u << 20;
// Reader history bound for blocks: the writer is pushed back, nothing lost.
inline constexpr int32_t kBlockReaderMaxSamples = 256;

// All six topics of one participant. Data topics carry the major version in
// their name so incompatible majors never match; Ack and AgentStatus do not.
struct Topics {
  explicit Topics(const dds::Participant& p);
  dds::Topic header, block, end, ack, status, monitoring;
};

// QoS of each topic (writer and reader use the same unless said).
dds::Qos block_writer_qos();  // reliable, KEEP_ALL, bounded by max_samples
dds::Qos block_reader_qos();  // reliable, KEEP_ALL, max_samples 256
dds::Qos control_qos();       // header/end: reliable, transient-local, KEEP_LAST 1 per run
dds::Qos ack_qos();           // reliable, KEEP_ALL, bounded
dds::Qos status_qos();        // heartbeat: reliable, KEEP_LAST 1 per pump
dds::Qos monitoring_qos();    // reliable, KEEP_LAST 16 per pump

// The agent's (publishing) side in one partition (the site).
struct AgentEndpoints {
  AgentEndpoints(dds_domainid_t domain, const std::string& partition);
  dds::Participant participant;
  Topics topics;
  dds::Publisher publisher;
  dds::Subscriber subscriber;
  dds::Writer<ambdiag_stream_RunHeader> header;
  dds::Writer<ambdiag_stream_SampleBlock> block;
  dds::Writer<ambdiag_stream_RunEnd> end;
  dds::Writer<ambdiag_stream_AgentStatus> status;
  dds::Writer<ambdiag_stream_MonitoringSnapshot> monitoring;
  dds::Reader<ambdiag_stream_Ack> ack;
};

// The server's side: subscribes in `partitions` (default "*": every site)
// and acknowledges in the same ones.
struct ServerEndpoints {
  ServerEndpoints(dds_domainid_t domain, const std::vector<std::string>& partitions);
  dds::Participant participant;
  Topics topics;
  dds::Publisher publisher;
  dds::Subscriber subscriber;
  dds::Reader<ambdiag_stream_RunHeader> header;
  dds::Reader<ambdiag_stream_SampleBlock> block;
  dds::Reader<ambdiag_stream_RunEnd> end;
  dds::Reader<ambdiag_stream_AgentStatus> status;
  dds::Reader<ambdiag_stream_MonitoringSnapshot> monitoring;
  dds::Writer<ambdiag_stream_Ack> ack;
};

// Per-pump partitions (docs/streaming.md, "Security"): an agent enrolled
// for pump P of site S publishes in "S/P" only, which its DDS Security
// permissions grant; the server reads every partition ("*") and binds a
// writer in "S/P" to pump P. Site and pump names must then be plain: no
// '/' and no wildcard characters.
bool plain_partition_name(const std::string& name);
std::string pump_partition(const std::string& site, const std::string& pump);
// The pump a writer publishing in `partitions` is bound to: the P of its one
// partition "S/P", or nothing for a site-wide writer (plain mode).
std::optional<std::string> pump_of_partitions(const std::vector<std::string>& partitions);

// A sequence<octet> that points at caller-owned bytes (no copy, not freed).
dds_sequence_octet borrow_octets(const void* data, size_t n);

}  // namespace ambdiag::stream
