// Compression of the REST server's replies. cpp-httplib 0.11 (Debian 12's)
// compresses a text reply itself, with brotli whenever the client accepts
// it, at brotli's default quality 11: 3.2 s for the 2.2 MB frf.csv of a
// run, where gzip takes 0.16 s for 12 % more bytes (a browser accepts both,
// so the web UI's run view waited seconds for its FRFs). The server gzips
// such replies itself instead and hands httplib the result as a content
// provider of known length, which httplib sends as it is.
#pragma once

#include <httplib.h>

namespace ambdiag::server::detail {

// Gzips `res`'s body when the client accepts gzip (named in Accept-Encoding,
// as httplib reads it: a weight of 0 is not understood), the content type is
// text (text/*, JSON, SVG, JavaScript; not the event stream) and the body
// is at least `min_bytes`; sets Content-Encoding and Vary. Leaves range
// requests, empty bodies and other types to httplib.
void gzip_reply(const httplib::Request& req, httplib::Response& res, size_t min_bytes = 1024);

}  // namespace ambdiag::server::detail
