// ambdiag-rest --db FILE [--http-port N] [--host H] [--tls-cert F --tls-key F]:
// the REST read side alone on an existing historian, until SIGINT or
// SIGTERM; with a certificate and key, HTTPS only.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ambdiag/core/error.h"
#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"

int main(int argc, char** argv) {
  ambdiag::server::RestOptions opt;
  opt.port = 8080;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--db" && has_value) {
      opt.db_path = argv[++i];
    } else if (a == "--http-port" && has_value) {
      opt.port = std::atoi(argv[++i]);
    } else if (a == "--host" && has_value) {
      opt.host = argv[++i];
    } else if (a == "--tls-cert" && has_value) {
      opt.tls_cert_path = argv[++i];
    } else if (a == "--tls-key" && has_value) {
      opt.tls_key_path = argv[++i];
    } else {
      std::fprintf(stderr, "usage: ambdiag-rest --db FILE [--http-port N] [--host H] [--tls-cert F --tls-key F]\n");
      return 2;
    }
  }
  if (opt.db_path.empty() || opt.port < 0 || opt.port > 65535 || opt.tls_cert_path.empty() != opt.tls_key_path.empty()) {
    std::fprintf(stderr, "usage: ambdiag-rest --db FILE [--http-port N] [--host H] [--tls-cert F --tls-key F]\n");
    return 2;
  }
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);  // before the server's threads start
  try {
    ambdiag::server::RestServer server(opt);
    const int port = server.start();
    std::fprintf(stderr, "ambdiag-rest: serving %s on %s://%s:%d/api/v1/health\n",
                 ambdiag::storage::display_location(opt.db_path).c_str(),
                 opt.tls_cert_path.empty() ? "http" : "https", opt.host.c_str(), port);
    int sig = 0;
    sigwait(&stop_signals, &sig);
    server.stop();
  } catch (const ambdiag::InputError& e) {
    std::fprintf(stderr, "ambdiag-rest: bad input: %s\n", e.what());
    return 3;
  }
  return 0;
}
