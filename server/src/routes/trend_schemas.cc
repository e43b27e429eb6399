// The trends' answers (rest.md "Trends"; trends/trend_json.h, the prognosis).
#include "routes/api_schemas.h"

namespace ambdiag::server::detail {

using namespace schema;

void add_trend_schemas(RouteTable& t) {
  t.add_schema("TrendPoint", object({{"time", time()}, {"value", number()}}, {{"sd", number()}, {"run_id", string()}}));
  t.add_schema("TrendBucket", object({{"time", time()},
                                      {"min", number()},
                                      {"max", number()},
                                      {"first", number()},
                                      {"last", number()},
                                      {"count", integer()}}));
  t.add_schema("Trend", object({{"name", string()},
                                {"unit", string()},
                                {"points", array(any_of({ref("TrendPoint"), ref("TrendBucket")}))}},
                               {{"count", integer()},
                                {"truncated", boolean()},
                                {"next_from", time()},
                                {"bucket_s", number()},
                                {"reference", object({{"mean", number()}, {"runs", integer()}, {"version", integer()}}, {{"sd", number()}})},
                                {"limits", object({})}}));
  t.add_schema("Prognosis", object({{"pump_id", string()},
                                    {"series", string()},
                                    {"unit", string()},
                                    {"limit", number()},
                                    {"limit_source", one_of({"query", "default"})},
                                    {"status", one_of({"ok", "limit reached", "not enough points", "not trending towards the limit"})},
                                    {"points", integer()},
                                    {"span_s", number()},
                                    {"truncated", boolean()}},
                                   {{"reason", string()},
                                    {"weighted", boolean()},
                                    {"slope_per_day", number()},
                                    {"slope_sd_per_day", number()},
                                    {"value_at_last", number()},
                                    {"estimated_at", string()},
                                    {"interval", object({{"level", number()}, {"from", string()}, {"to", string()}})}}));
}

}  // namespace ambdiag::server::detail
