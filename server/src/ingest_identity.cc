#include "ingest_identity.h"

#include <cstdio>

#include "ambdiag/proto/stream.h"
#include "ambdiag/server/ingest.h"

namespace ambdiag::server {

std::optional<std::string> WriterPumps::bound_pump(const dds::Entity& reader, dds_instance_handle_t writer) {
  if (auto it = cache_.find(writer); it != cache_.end()) return it->second;
  const auto partitions = dds::matched_writer_partitions(reader, writer);
  // A writer gone before its sample was taken is not cached (its handle
  // will not come back) and is taken as unbound: the window is the receive
  // thread's latency, and its data is checked like any other.
  if (!partitions) return std::nullopt;
  if (cache_.size() >= kMaxCached) cache_.clear();
  return cache_[writer] = stream::pump_of_partitions(*partitions);
}

SecurityLog::SecurityLog(IngestCounters& counters) : counters_(counters) { dds_set_log_sink(&SecurityLog::sink, this); }

SecurityLog::~SecurityLog() { dds_set_log_sink(nullptr, nullptr); }  // back to Cyclone's own (stderr)

bool SecurityLog::is_security_refusal(const std::string& line) {
  // The wording of Cyclone 0.10's warnings (ddsi_handshake.c,
  // ddsi_security_omg.c) and of its security plugins' exceptions.
  static const char* const kMarks[] = {"andshake",          "remote identity", "Certificate",  "certificate",
                                       "is not allowed",    "Access denied",   "permissions",  "Permissions",
                                       "security_attributes mismatch"};
  for (const char* m : kMarks)
    if (line.find(m) != std::string::npos) return true;
  return false;
}

void SecurityLog::sink(void* self, const dds_log_data_t* data) {
  // As Cyclone's default sink: the header (time, domain, thread) and the line.
  std::fwrite(data->message - data->hdrsize, 1, data->hdrsize + data->size + 1, stderr);
  std::fflush(stderr);
  if ((data->priority & (DDS_LC_WARNING | DDS_LC_ERROR)) == 0) return;
  if (is_security_refusal(std::string(data->message, data->size))) static_cast<SecurityLog*>(self)->counters_.reject("dds_security");
}

}  // namespace ambdiag::server
