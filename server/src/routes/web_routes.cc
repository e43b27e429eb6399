// What the web UI (web/, issue 20) needs from the server: its own files
// (GET / and GET /ui/..., no token: rest.md "Who may do what"), the whole
// fleet's pump views in one request (GET /api/v1/fleet: one request per
// pump would take 20 s of a 50/s rate limit for 1000 pumps), who the
// caller is (GET /api/v1/me: the UI offers only the actions of its role)
// and the model's and the modal fit's FRF of a run as data (GET
// .../model_frf.csv, .../fit_frf.csv, so the browser draws them over the
// measured one).
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "analysis/model_frf.h"
#include "analysis/views.h"
#include "rest_json.h"
#include "routes/json_schema.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

namespace fs = std::filesystem;

// Content types of the files the UI ships; anything else is not served
// (the build puts only these in the folder).
const char* content_type(const std::string& ext) {
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".json") return "application/json";
  if (ext == ".png") return "image/png";
  if (ext == ".ico") return "image/x-icon";
  return nullptr;
}

// The file under `dir` that the decoded relative path names, or an error.
// Each part must be a plain name (letters, digits, '.', '_', '-', not
// starting with '.'): no "..", no hidden files, no '/' that came as %2F;
// then the resolved file must still lie inside `dir` (a symlink out of it
// is refused too).
fs::path web_file(const std::string& dir, const std::string& rel) {
  if (rel.size() > 200) throw InputError("path: longer than 200 bytes");
  std::stringstream parts(rel);
  for (std::string p; std::getline(parts, p, '/');) {
    if (p.empty() || p[0] == '.') throw InputError("path: '" + p + "' is not a file name of the web UI");
    for (const char ch : p)
      if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '_' && ch != '-')
        throw InputError("path: '" + p + "' holds a character other than letters, digits, '.', '_' and '-'");
  }
  std::error_code ec;
  const fs::path root = fs::canonical(dir, ec);
  if (ec)
    throw NotFoundError("the web UI is not installed: " + dir + " is missing (build it: web/README.md)");
  const fs::path file = fs::weakly_canonical(root / rel, ec);
  const auto [end, _] = std::mismatch(root.begin(), root.end(), file.begin(), file.end());
  if (ec || end != root.end() || !fs::is_regular_file(file))
    throw NotFoundError("the web UI has no file '" + rel + "'");
  return file;
}

void send_web_file(RouteContext& c, const std::string& rel) {
  if (c.opt.web_dir.empty())
    throw NotFoundError(
        "the web UI is not installed with this server (ambdiag serve --web-dir DIR; web/README.md)");
  const fs::path file = web_file(c.opt.web_dir, rel);
  const char* type = content_type(file.extension().string());
  if (!type) throw NotFoundError("the web UI has no file '" + rel + "' (not a type it serves)");
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) throw NotFoundError("the web UI has no file '" + rel + "'");
  // Not content-hashed names, so no long max-age: the browser revalidates
  // each time (no-cache) and gets 304 while size and mtime are unchanged.
  const std::string etag =
      "\"" + std::to_string(st.st_size) + "-" +
      std::to_string(static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec) + "\"";
  c.res.set_header("ETag", etag);
  c.res.set_header("Cache-Control", "no-cache");
  c.res.set_header("X-Content-Type-Options", "nosniff");
  if (file.extension() == ".html") {
    // Only our own files: no inline script, no outside origin (plant networks are closed anyway).
    c.res.set_header("Content-Security-Policy",
                     "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
                     "frame-ancestors 'none'; base-uri 'none'; form-action 'none'");
    c.res.set_header("Referrer-Policy", "no-referrer");
  }
  if (c.req.get_header_value("If-None-Match") == etag) {
    c.res.status = 304;
    return;
  }
  std::ifstream in(file, std::ios::binary);
  std::ostringstream body;
  body << in.rdbuf();
  if (!in) throw NotFoundError("the web UI cannot read '" + rel + "'");
  c.res.status = 200;
  // httplib gzips or brotli-encodes the text types when the client accepts it.
  c.res.set_content(body.str(), type);
}

// Every pump's view (rest.md's GET /pumps/{id}) and its run summary.
void get_fleet(RouteContext& c) {
  auto h = c.pool.acquire();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& p : h->list_pumps()) {
    nlohmann::json j = pump_json(p);
    if (auto v = pump_view(*h, p.pump_id, c.opt.proposed_reference_runs)) j.update(*v);
    list.push_back(std::move(j));
  }
  send_json(c.res, 200, {{"pumps", list}});
}

// The caller as the token (or --anonymous-read) makes it: the UI shows
// the actions of this role and hides or disables the rest.
void get_me(RouteContext& c) {
  send_json(c.res, 200,
            {{"name", c.caller.name}, {"role", storage::to_string(c.caller.role)}, {"anonymous", !c.caller.from_token}});
}

void send_csv(RouteContext& c, const std::string& csv) {
  c.res.status = 200;
  c.res.set_content(csv, "text/csv");
}

}  // namespace

void add_web_routes(RouteTable& t) {
  using storage::Role;
  auto& index = t.add({"GET",
                       "/",
                       std::nullopt,
                       "the web UI (no token: its API calls carry one)",
                       [](RouteContext& c, const PathParams&) { send_web_file(c, "index.html"); },
                       {},
                       "text/html"});
  index.description =
      "index.html of the UI's folder (ambdiag serve --web-dir; web/README.md); 404 when the UI is not "
      "installed.";
  auto& files = t.add({"GET",
                       "/ui/{path*}",
                       std::nullopt,
                       "a file of the web UI (scripts, styles)",
                       [](RouteContext& c, const PathParams& p) { send_web_file(c, p.at("path")); },
                       {},
                       "text/plain"});
  files.description =
      "Served from the UI's folder with the content type of its extension, ETag and Cache-Control: no-cache "
      "(304 on If-None-Match), compressed when the client accepts it; names of letters, digits, '.', '_', "
      "'-' "
      "only (400 otherwise, so no '..'), nothing outside the folder.";
  t.add({"GET", "/api/v1/fleet", Role::viewer,
         "every pump's view (as GET /api/v1/pumps/{pump_id}) with its run count, in one reply",
         [](RouteContext& c, const PathParams&) { get_fleet(c); }})
      .response_schema = schema::object({{"pumps", schema::array(schema::ref("Pump"))}});
  auto& me = t.add({"GET", "/api/v1/me", Role::viewer, "who the request's token (or --anonymous-read) makes the caller",
         [](RouteContext& c, const PathParams&) { get_me(c); }});
  me.response_schema = schema::object({{"name", schema::string()}, {"role", schema::role()}, {"anonymous", schema::boolean()}});
  me.description =
      "{\"name\", \"role\": \"viewer|operator|engineer|admin\", \"anonymous\": bool}: the token's name and role, "
      "or name \"anonymous\" with role viewer for a request without a token on a server with --anonymous-read. "
      "The web UI offers only the actions of this role.";
  t.add({"GET",
         "/api/v1/runs/{run_id*}/model_frf.csv",
         Role::viewer,
         "the model's FRF on the run's grid and entries at its speed (the model version of its analysis)",
         [](RouteContext& c, const PathParams& p) { send_csv(c, model_frf_csv(*c.pool.acquire(), p.at("run_id"))); },
         {},
         "text/csv"})
      .errors = {410};
  auto& fit = t.add({"GET",
         "/api/v1/runs/{run_id*}/fit_frf.csv",
         Role::viewer,
         "the modal fit's FRF on the run's grid, for the entries the fit used",
         [](RouteContext& c, const PathParams& p) { send_csv(c, fit_frf_csv(*c.pool.acquire(), p.at("run_id"))); },
         {},
         "text/csv"});
  fit.errors = {410};
  fit.description =
      "The rational model the analysis fitted (its fit_model.json) evaluated on the frequency grid of the run's "
      "frf.csv: the curve the modes and damping ratios come from. 404 until the analysis is done, and for an "
      "analysis made before fit_model.json was kept (the run's next analysis keeps it).";
}

}  // namespace ambdiag::server::detail

namespace ambdiag::server {

std::string find_web_dir(const std::string& exe) {
  std::error_code ec;
  const std::filesystem::path bin = std::filesystem::canonical(exe, ec).parent_path();
  if (ec) return "";
  for (const auto& dir : {bin / ".." / "web", bin / ".." / "share" / "ambdiag" / "web"})
    if (std::filesystem::is_regular_file(dir / "index.html", ec))
      return std::filesystem::canonical(dir, ec).string();
  return "";
}

}  // namespace ambdiag::server
