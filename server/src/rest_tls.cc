#include "rest_tls.h"

#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>

#include <cstdio>

#include "ambdiag/core/error.h"

namespace ambdiag::server::detail {

namespace {

struct FileCloser {
  void operator()(FILE* f) const { std::fclose(f); }
};
struct X509Free {
  void operator()(X509* x) const { X509_free(x); }
};
struct KeyFree {
  void operator()(EVP_PKEY* k) const { EVP_PKEY_free(k); }
};

std::unique_ptr<FILE, FileCloser> open_readable(const std::string& path, const char* what) {
  std::unique_ptr<FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) throw InputError(std::string(what) + " " + path + ": cannot be read");
  return f;
}

}  // namespace

void check_tls_files(const std::string& cert_path, const std::string& key_path) {
  std::unique_ptr<X509, X509Free> cert(PEM_read_X509(open_readable(cert_path, "--tls-cert").get(), nullptr, nullptr, nullptr));
  if (!cert) throw InputError("--tls-cert " + cert_path + ": not a PEM certificate");
  std::unique_ptr<EVP_PKEY, KeyFree> key(
      PEM_read_PrivateKey(open_readable(key_path, "--tls-key").get(), nullptr, nullptr, nullptr));
  if (!key) throw InputError("--tls-key " + key_path + ": not a PEM private key (or protected by a passphrase)");
  if (X509_check_private_key(cert.get(), key.get()) != 1)
    throw InputError("--tls-key " + key_path + ": is not the private key of --tls-cert " + cert_path);
  ERR_clear_error();
}

std::unique_ptr<httplib::Server> make_tls_server(const std::string& cert_path, const std::string& key_path) {
  check_tls_files(cert_path, key_path);
  auto server = std::make_unique<httplib::SSLServer>([&](SSL_CTX& ctx) {
    SSL_CTX_set_options(&ctx, SSL_OP_NO_COMPRESSION | SSL_OP_NO_SESSION_RESUMPTION_ON_RENEGOTIATION);
    return SSL_CTX_set_min_proto_version(&ctx, TLS1_2_VERSION) == 1 &&
           SSL_CTX_use_certificate_chain_file(&ctx, cert_path.c_str()) == 1 &&
           SSL_CTX_use_PrivateKey_file(&ctx, key_path.c_str(), SSL_FILETYPE_PEM) == 1 &&
           SSL_CTX_check_private_key(&ctx) == 1;
  });
  if (!server->is_valid()) throw InputError("--tls-cert " + cert_path + " / --tls-key " + key_path + ": OpenSSL refused them");
  return server;
}

}  // namespace ambdiag::server::detail
