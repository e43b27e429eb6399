// The named schemas (OpenAPI components) of the REST answers, one small
// file per domain, each registered by its domain's add_*_routes before the
// routes that reference them (schema::ref). Required keys are rest.md's
// (those not marked `?`); where rest.md is silent, the keys the handler
// always writes (docs/service.md "OpenAPI").
#pragma once

#include "routes/json_schema.h"
#include "routes/route_table.h"

namespace ambdiag::server::detail {

// Health, PumpSummary, Run, MonitoringSnapshot (read_schemas.cc).
void add_read_schemas(RouteTable& t);
// Pump, Analysis, FittedMode, Job (analysis_schemas.cc).
void add_analysis_schemas(RouteTable& t);
// Alarm, AlarmTransition, AlarmJournalEvent, AlarmKpis, AlarmRule,
// AlarmRules (alarm_schemas.cc).
void add_alarm_schemas(RouteTable& t);
// Trend, TrendPoint, TrendBucket, Prognosis (trend_schemas.cc).
void add_trend_schemas(RouteTable& t);

}  // namespace ambdiag::server::detail
