// The web UI's files over real HTTP (server/src/routes/web_routes.cc): served
// without a token with their content types, revalidated by ETag, compressed
// when asked, and nothing outside the UI's folder whatever the path says;
// GET /api/v1/me tells the UI its caller's role.
#include <gtest/gtest.h>
#include <httplib.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "ambdiag/server/rest_server.h"
#include "ambdiag/storage/historian.h"
#include "test_support.h"

namespace ambdiag::server {
namespace {

namespace fs = std::filesystem;

class WebRoutes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ambdiag::testing::scratch_dir();
    db_ = (dir_ / "h.db").string();
    storage::Historian::open(db_);
    web_ = dir_ / "web";
    fs::create_directories(web_ / "js");
    write(web_ / "index.html", "<!doctype html><title>ui</title>");
    write(web_ / "js" / "main.js",
          "export const x = 1;\n" + std::string(4000, ' ') + "// padding that compresses\n");
    write(web_ / "app.css", "body{}");
    write(web_ / "notes.txt", "not a type the UI serves");
    write(web_ / ".hidden.js", "hidden");
    write(dir_ / "secret.js", "SECRET");  // beside the UI's folder, not in it
    fs::create_symlink(dir_ / "secret.js", web_ / "link.js");
  }
  static void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

  void start(const std::string& web_dir, bool anonymous_read = false) {
    RestOptions opt;
    opt.db_path = db_;
    opt.host = "127.0.0.1";
    opt.web_dir = web_dir;
    opt.anonymous_read = anonymous_read;
    server_ = std::make_unique<RestServer>(opt);
    port_ = server_->start();
  }
  httplib::Result get(const std::string& path, const httplib::Headers& h = {}) {
    httplib::Client c("127.0.0.1", port_);
    c.set_decompress(false);
    return c.Get(path, h);
  }

  fs::path dir_, web_;
  std::string db_;
  std::unique_ptr<RestServer> server_;
  int port_ = 0;
};

TEST_F(WebRoutes, ServesTheUiWithoutATokenWithContentTypesAndCaching) {
  start(web_.string());
  const auto index = get("/");
  ASSERT_TRUE(index);
  EXPECT_EQ(index->status, 200);
  EXPECT_EQ(index->body, "<!doctype html><title>ui</title>");
  EXPECT_EQ(index->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_EQ(index->get_header_value("Cache-Control"), "no-cache");
  EXPECT_NE(index->get_header_value("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
  const auto js = get("/ui/js/main.js");
  ASSERT_TRUE(js);
  EXPECT_EQ(js->status, 200);
  EXPECT_EQ(js->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(js->get_header_value("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(get("/ui/app.css")->get_header_value("Content-Type"), "text/css; charset=utf-8");
  // Unchanged: 304 without a body; changed: the new file with a new ETag.
  const std::string etag = js->get_header_value("ETag");
  ASSERT_FALSE(etag.empty());
  const auto again = get("/ui/js/main.js", {{"If-None-Match", etag}});
  EXPECT_EQ(again->status, 304);
  EXPECT_TRUE(again->body.empty());
  write(web_ / "js" / "main.js", "export const x = 2;\n");
  const auto changed = get("/ui/js/main.js", {{"If-None-Match", etag}});
  EXPECT_EQ(changed->status, 200);
  EXPECT_EQ(changed->body, "export const x = 2;\n");
  EXPECT_NE(changed->get_header_value("ETag"), etag);
}

TEST_F(WebRoutes, CompressesTextWhenTheClientAcceptsGzip) {
  start(web_.string());
  const auto r = get("/ui/js/main.js", {{"Accept-Encoding", "gzip"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Encoding"), "gzip");
  EXPECT_LT(r->body.size(), 1000u);  // 4 kB of mostly spaces
}

// A browser accepts brotli too; httplib's own brotli (quality 11) took 3.2 s
// for a run's 2.2 MB frf.csv. The server gzips instead (http_compress.h):
// the same bytes come back, gzip also where br is offered first, and
// nothing where the client takes no compression.
TEST_F(WebRoutes, GzipsLargeTextEvenWhereBrotliIsAcceptedAndTheBytesSurvive) {
  std::string big;
  for (int i = 0; big.size() < 3'000'000; ++i) big += "// line " + std::to_string(i * 7919 % 100003) + "\n";
  write(web_ / "js" / "big.js", big);
  start(web_.string());
  httplib::Client c("127.0.0.1", port_);  // decompresses, as a browser does
  const auto r = c.Get("/ui/js/big.js", {{"Accept-Encoding", "br, gzip, deflate"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Encoding"), "gzip");
  EXPECT_EQ(r->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_EQ(r->get_header_value_count("Content-Type"), 1u);
  EXPECT_EQ(r->body, big);
  const auto raw = get("/ui/js/big.js", {{"Accept-Encoding", "br, gzip"}});
  EXPECT_LT(raw->body.size(), big.size() / 2);
  EXPECT_EQ(std::stoul(raw->get_header_value("Content-Length")), raw->body.size());
  const auto plain = get("/ui/js/big.js", {{"Accept-Encoding", "identity"}});
  EXPECT_EQ(plain->get_header_value("Content-Encoding"), "");
  EXPECT_EQ(plain->body, big);
  // HEAD: the headers, no body.
  const auto head = c.Head("/ui/js/big.js", {{"Accept-Encoding", "gzip"}});
  ASSERT_TRUE(head);
  EXPECT_EQ(head->status, 200);
  EXPECT_TRUE(head->body.empty());
}

TEST_F(WebRoutes, NothingOutsideTheFolderOrHiddenOrOfAnotherTypeIsServed) {
  start(web_.string());
  for (const std::string path :
       {"/ui/../secret.js", "/ui/%2e%2e/secret.js", "/ui/..%2Fsecret.js", "/ui/js/../../secret.js",
        "/ui/.hidden.js", "/ui/link.js", "/ui/notes.txt", "/ui/js", "/ui/missing.js",
        "/ui/js%2Fmain.js%00.css", "/ui/a%5Cb.js", "/ui/%2Fetc%2Fpasswd"}) {
    const auto r = get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_TRUE(r->status == 400 || r->status == 404) << path << ": " << r->status << " " << r->body;
    EXPECT_EQ(r->body.find("SECRET"), std::string::npos) << path;
    EXPECT_EQ(r->body.find("hidden\""), std::string::npos) << path;
    EXPECT_NE(r->body.find("\"error\""), std::string::npos) << path << ": " << r->body;
  }
  // The API stays behind its token.
  EXPECT_EQ(get("/api/v1/pumps")->status, 401);
  EXPECT_EQ(get("/api/v1/fleet")->status, 401);
}

TEST_F(WebRoutes, WithoutTheUiInstalledTheRootSaysSo) {
  start("");
  const auto r = get("/");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
  EXPECT_NE(r->body.find("--web-dir"), std::string::npos) << r->body;
  server_.reset();
  start((dir_ / "nowhere").string());
  EXPECT_EQ(get("/ui/js/main.js")->status, 404);
}

// The UI shows only the actions of the caller's role: /me says which,
// for a token of each role and for a reader without one.
TEST_F(WebRoutes, MeTellsTheTokensNameAndRoleOrAnonymousUnderAnonymousRead) {
  std::map<std::string, std::string> secret;
  {
    auto h = storage::Historian::open(db_);
    secret["vera"] = h.add_token("vera", storage::Role::viewer);
    secret["otto"] = h.add_token("otto", storage::Role::operator_);
    secret["erin"] = h.add_token("erin", storage::Role::engineer);
  }
  const auto me = [&](const std::string& who) {
    httplib::Headers hd;
    if (!who.empty()) hd.emplace("Authorization", "Bearer " + (secret.count(who) ? secret[who] : who));
    const auto r = get("/api/v1/me", hd);
    EXPECT_TRUE(r);
    return std::make_pair(r->status, r->status == 200 ? nlohmann::json::parse(r->body) : nlohmann::json());
  };
  for (const bool anonymous_read : {false, true}) {
    server_.reset();
    start(web_.string(), anonymous_read);
    for (const auto& [who, role] : std::map<std::string, std::string>{{"vera", "viewer"}, {"otto", "operator"}, {"erin", "engineer"}}) {
      const auto [status, j] = me(who);
      EXPECT_EQ(status, 200);
      EXPECT_EQ(j, (nlohmann::json{{"name", who}, {"role", role}, {"anonymous", false}}));
    }
    EXPECT_EQ(me("not-a-token").first, 401);  // a wrong token is refused, even where reading is open
    const auto [status, j] = me("");
    if (anonymous_read) {
      EXPECT_EQ(status, 200);
      EXPECT_EQ(j, (nlohmann::json{{"name", "anonymous"}, {"role", "viewer"}, {"anonymous", true}}));
    } else {
      EXPECT_EQ(status, 401);
    }
  }
}

TEST(FindWebDir, FindsTheBuildTreesFolderNextToTheBinary) {
  const fs::path root = ambdiag::testing::scratch_dir();
  fs::create_directories(root / "cli");
  fs::create_directories(root / "share" / "ambdiag" / "web");
  std::ofstream(root / "cli" / "ambdiag") << "";
  EXPECT_EQ(find_web_dir((root / "cli" / "ambdiag").string()), "");
  std::ofstream(root / "share" / "ambdiag" / "web" / "index.html") << "";
  fs::create_directories(root / "bin");
  std::ofstream(root / "bin" / "ambdiag") << "";
  EXPECT_EQ(find_web_dir((root / "bin" / "ambdiag").string()),
            fs::canonical(root / "share" / "ambdiag" / "web").string());
  fs::create_directories(root / "web");
  std::ofstream(root / "web" / "index.html") << "";
  EXPECT_EQ(find_web_dir((root / "cli" / "ambdiag").string()), fs::canonical(root / "web").string());
}

}  // namespace
}  // namespace ambdiag::server
