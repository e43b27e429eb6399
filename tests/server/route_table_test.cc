// RouteTable: which route a path and method reach, 405 versus 404, and the
// patterns refused when the table is built.
#include "routes/route_table.h"

#include <stdexcept>

#include <gtest/gtest.h>

namespace ambdiag::server::detail {
namespace {

RouteHandler noop() {
  return [](RouteContext&, const PathParams&) {};
}

RouteTable table() {
  RouteTable t;
  t.add({"GET", "/api/v1/pumps/{pump_id}", storage::Role::viewer, "pump", noop()});
  t.add({"GET", "/api/v1/pumps/{pump_id}/model", storage::Role::viewer, "model", noop()});
  t.add({"PUT", "/api/v1/pumps/{pump_id}/model", storage::Role::engineer, "put model", noop()});
  t.add({"GET", "/api/v1/runs/{run_id*}", storage::Role::viewer, "run", noop()});
  t.add({"GET", "/api/v1/runs/{run_id*}/analysis", storage::Role::viewer, "analysis", noop()});
  t.add({"GET", "/api/v1/jobs/{job_id}/files/{name}", storage::Role::viewer, "file", noop()});
  return t;
}

TEST(RouteTable, ParametersAreTakenFromThePath) {
  const auto t = table();
  const auto f = t.find("GET", {"api", "v1", "jobs", "12", "files", "explain.svg"});
  ASSERT_NE(f.route, nullptr);
  EXPECT_EQ(f.route->summary, "file");
  EXPECT_EQ(f.params.at("job_id"), "12");
  EXPECT_EQ(f.params.at("name"), "explain.svg");
}

TEST(RouteTable, ARunIdWithUnencodedSlashesStillFindsItsRunAndTheMoreSpecificRouteWins) {
  const auto t = table();
  auto f = t.find("GET", {"api", "v1", "runs", "P-1", "2026-01-01T00:00:00Z"});
  ASSERT_NE(f.route, nullptr);
  EXPECT_EQ(f.route->summary, "run");
  EXPECT_EQ(f.params.at("run_id"), "P-1/2026-01-01T00:00:00Z");
  f = t.find("HEAD", {"api", "v1", "runs", "P-1", "r7", "analysis"});
  ASSERT_NE(f.route, nullptr);
  EXPECT_EQ(f.route->summary, "analysis");
  EXPECT_EQ(f.params.at("run_id"), "P-1/r7");
}

TEST(RouteTable, AKnownPathWithAnotherMethodIs405WithItsAllowList) {
  const auto t = table();
  auto f = t.find("POST", {"api", "v1", "pumps", "P-1", "model"});
  EXPECT_EQ(f.route, nullptr);
  EXPECT_TRUE(f.path_known);
  EXPECT_EQ(f.allow, "GET, HEAD, PUT");
  f = t.find("PUT", {"api", "v1", "runs", "r", "analysis"});
  EXPECT_TRUE(f.path_known);
  EXPECT_EQ(f.allow, "GET, HEAD");  // the analysis route, not the run's
  f = t.find("GET", {"api", "v1", "pumps", "P-1", "nothing"});
  EXPECT_FALSE(f.path_known);
  f = t.find("GET", {"api", "v1", "pumps", ""});  // an empty pump_id is no pump
  EXPECT_FALSE(f.path_known);
}

TEST(RouteTable, ATrailingSlashReachesOnlyARouteThatAllowsIt) {
  auto t = table();
  Route root{"GET", "/api/v1/grafana", storage::Role::viewer, "grafana", noop()};
  root.trailing_slash = true;
  t.add(std::move(root));
  auto f = t.find("GET", {"api", "v1", "grafana", ""});
  ASSERT_NE(f.route, nullptr);
  EXPECT_EQ(f.route->summary, "grafana");
  EXPECT_NE(t.find("GET", {"api", "v1", "grafana"}).route, nullptr);
  EXPECT_EQ(t.find("GET", {"api", "v1", "pumps", "P-1", "model", ""}).route, nullptr);
}

TEST(RouteTable, MalformedOrDuplicateRoutesAreRefusedWhenAdded) {
  RouteTable t = table();
  EXPECT_THROW(t.add({"GET", "/api/v1/pumps/{pump_id}", std::nullopt, "again", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"DELETE", "/api/v1/x", std::nullopt, "", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"GET", "api/v1/x", std::nullopt, "", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"GET", "/api//x", std::nullopt, "", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"GET", "/api/{a*}/{b*}", std::nullopt, "", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"GET", "/api/{a", std::nullopt, "", noop()}), std::logic_error);
  EXPECT_THROW(t.add({"GET", "/api/y", std::nullopt, "", nullptr}), std::logic_error);
}

}  // namespace
}  // namespace ambdiag::server::detail
