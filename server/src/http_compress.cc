#include "http_compress.h"

#include <zlib.h>

#include <memory>
#include <string>

namespace ambdiag::server::detail {

namespace {

bool compressible(const std::string& type) {
  if (type.rfind("text/event-stream", 0) == 0) return false;
  for (const char* prefix : {"text/", "application/json", "image/svg+xml", "application/javascript"})
    if (type.rfind(prefix, 0) == 0) return true;
  return false;
}

// The gzip stream of `in` (level 6: zlib's default), or "" on a zlib error.
std::string gzip(const std::string& in) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return "";
  std::string out(deflateBound(&z, static_cast<uLong>(in.size())), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return rc == Z_STREAM_END ? out : "";
}

}  // namespace

void gzip_reply(const httplib::Request& req, httplib::Response& res, size_t min_bytes) {
  if (res.body.size() < min_bytes || res.body.size() > 0xffffffffu || !req.ranges.empty()) return;
  const std::string type = res.get_header_value("Content-Type");
  if (!compressible(type) || req.get_header_value("Accept-Encoding").find("gzip") == std::string::npos) return;
  auto data = std::make_shared<std::string>(gzip(res.body));
  if (data->empty()) return;  // httplib compresses it then
  res.body.clear();
  res.headers.erase("Content-Type");  // set again by set_content_provider
  res.set_header("Content-Encoding", "gzip");
  res.set_header("Vary", "Accept-Encoding");
  res.set_content_provider(
      data->size(), type,
      [data](size_t offset, size_t length, httplib::DataSink& sink) { return sink.write(data->data() + offset, length); });
}

}  // namespace ambdiag::server::detail
