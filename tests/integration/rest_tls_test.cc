// HTTPS for the REST service (issue 21, docs/service.md "HTTPS"): a real
// `ambdiag serve --tls-cert --tls-key` with a certificate from the deploy
// script's CA; a loopback capture checks that a token never crosses in clear.
#include <httplib.h>
#include <openssl/ssl.h>

#include "security_fixture.h"

namespace ambdiag::testing {
namespace {

constexpr char kToken[] = "TOKEN-THAT-MUST-NOT-CROSS-IN-CLEAR-7f3a";

class RestTlsTest : public PkiTest {
 protected:
  void SetUp() override {
    PkiTest::SetUp();
    pki_ok("tls " + pki_dir.string() + " localhost 127.0.0.1");
  }
  std::unique_ptr<Process> serve_tls(const fs::path& cert, const fs::path& key) {
    return start_server({"--workers", "0", "--tls-cert", cert.string(), "--tls-key", key.string()});
  }
  // A client that trusts the test CA only.
  std::unique_ptr<httplib::SSLClient> client(int port) {
    auto c = std::make_unique<httplib::SSLClient>("127.0.0.1", port);
    c->set_ca_cert_path((pki_dir / "ca.pem").string().c_str());
    c->enable_server_certificate_verification(true);
    c->set_connection_timeout(5, 0);
    return c;
  }
};

TEST_F(RestTlsTest, HttpsServesHealthPlainHttpFailsAndTheTokenNeverCrossesInClear) {
  LoopbackCapture capture(dir, "tcp");
  auto server = serve_tls(pki_dir / "tls" / "server.pem", pki_dir / "tls" / "server.key");
  const int port = rest_port(*server);
  ASSERT_GT(port, 0) << server->log();
  EXPECT_NE(server->log().find("(HTTPS)"), std::string::npos) << server->log();

  auto https = client(port);
  const auto health = https->Get("/api/v1/health");
  ASSERT_TRUE(health) << "HTTPS request failed: " << httplib::to_string(health.error());
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(nlohmann::json::parse(health->body).value("status", ""), "ok") << health->body;
  // A path of this test's own: other tests' plain requests on loopback (ctest -j)
  // are in the capture too.
  const auto pumps = https->Get("/api/v1/pumps?tls-test-marker", {{"Authorization", std::string("Bearer ") + kToken}});
  ASSERT_TRUE(pumps);
  EXPECT_EQ(pumps->status, 401) << pumps->body;  // an unknown token, refused: it did reach the server

  httplib::Client plain("127.0.0.1", port);
  plain.set_connection_timeout(2, 0);
  plain.set_read_timeout(2, 0);
  const auto p = plain.Get("/api/v1/health", {{"Authorization", std::string("Bearer ") + kToken}});
  EXPECT_FALSE(p && p->status == 200) << "plain HTTP was answered on the TLS port";

  // TLS 1.1 is refused (1.2 at least).
  auto old = client(port);
  SSL_CTX_set_max_proto_version(old->ssl_context(), TLS1_1_VERSION);
  EXPECT_FALSE(old->Get("/api/v1/health")) << "a TLS 1.1 client was served";

  const std::string wire = capture.stop();
  if (!capture.available()) GTEST_SKIP() << "HTTPS checked; no loopback capture for the clear-text check: " << capture.why();
  // Handshakes and requests at least (a TLS handshake alone is about 2 KB).
  EXPECT_GT(wire.size(), 1000u) << "the capture saw too little to judge";
  EXPECT_NE(wire.find("GET /api/v1/health"), std::string::npos) << "the capture misses the plain request (control)";
  // The plain request above sent the token in clear on purpose: only its
  // one copy may appear, never the HTTPS request's.
  size_t copies = 0;
  for (size_t at = wire.find(kToken); at != std::string::npos; at = wire.find(kToken, at + 1)) ++copies;
  EXPECT_LE(copies, 1u) << "the token crossed loopback in clear over HTTPS";
  EXPECT_EQ(wire.find("tls-test-marker"), std::string::npos) << "an HTTPS request crossed in clear";
}

TEST_F(RestTlsTest, MissingUnreadableOrMismatchedFilesExitThreeNamingTheFile) {
  const fs::path cert = pki_dir / "tls" / "server.pem", key = pki_dir / "tls" / "server.key";
  auto missing = serve_tls(dir / "no-such.pem", key);
  EXPECT_EQ(missing->wait(15s), 3) << missing->log();
  EXPECT_NE(missing->log().find((dir / "no-such.pem").string() + ": cannot be read"), std::string::npos) << missing->log();
  auto not_pem = serve_tls(pki_dir / "governance.xml", key);
  EXPECT_EQ(not_pem->wait(15s), 3) << not_pem->log();
  EXPECT_NE(not_pem->log().find("governance.xml: not a PEM certificate"), std::string::npos) << not_pem->log();
  auto other_key = serve_tls(cert, pki_dir / "server" / "identity.key");
  EXPECT_EQ(other_key->wait(15s), 3) << other_key->log();
  EXPECT_NE(other_key->log().find("identity.key: is not the private key of --tls-cert"), std::string::npos) << other_key->log();
}

}  // namespace
}  // namespace ambdiag::testing
