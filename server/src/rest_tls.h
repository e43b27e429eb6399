// HTTPS for the REST service (docs/service.md, "HTTPS"): an SSLServer whose
// OpenSSL context takes TLS 1.2 at least, the certificate chain and the key.
#pragma once

#include <httplib.h>

#include <memory>
#include <string>

namespace ambdiag::server::detail {

// Checks the files before anything listens and throws InputError naming the
// one at fault: missing or unreadable, not a PEM certificate / private key,
// or a key that is not the certificate's.
void check_tls_files(const std::string& cert_path, const std::string& key_path);

// A server that speaks HTTPS only (TLS >= 1.2) with that certificate and key.
std::unique_ptr<httplib::Server> make_tls_server(const std::string& cert_path, const std::string& key_path);

}  // namespace ambdiag::server::detail
