// What the server learns of who sent a sample (docs/streaming.md, "Security").
//
// WriterPumps: the pump a remote writer is bound to by its partition. An
// agent enrolled for pump P publishes in partition "S/P" only (DDS Security
// permissions grant it no other), so a sample claiming another pump is
// refused (`pump_partition`). A site-wide writer (plain mode, lab bench) is
// bound to no pump. Looked up once per writer through the reader that took
// its sample, then cached.
//
// SecurityLog: Cyclone reports the remote participants and endpoints its
// security plugins refuse (failed handshakes, untrusted or revoked
// certificates, permissions that do not grant a remote writer) only in its
// log, as warnings. While it exists it takes Cyclone's log sink, writes
// every line to stderr as before and counts the security refusals as
// ingest rejections of reason `dds_security`.
#pragma once

#include <dds/dds.h>

#include <cstddef>
#include <optional>
#include <string>
#include <unordered_map>

#include "ambdiag/proto/dds.h"

namespace ambdiag::server {

struct IngestCounters;

class WriterPumps {
 public:
  std::optional<std::string> bound_pump(const dds::Entity& reader, dds_instance_handle_t writer);

 private:
  static constexpr size_t kMaxCached = 4096;  // writers come and go over months: forget them all now and then
  std::unordered_map<dds_instance_handle_t, std::optional<std::string>> cache_;
};

class SecurityLog {
 public:
  explicit SecurityLog(IngestCounters& counters);
  ~SecurityLog();
  SecurityLog(const SecurityLog&) = delete;
  SecurityLog& operator=(const SecurityLog&) = delete;
  // True for a Cyclone log line reporting a security refusal.
  static bool is_security_refusal(const std::string& line);

 private:
  static void sink(void* self, const dds_log_data_t* data);
  IngestCounters& counters_;
};

}  // namespace ambdiag::server
