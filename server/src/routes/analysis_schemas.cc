// The analysis side's answers (rest.md "Pumps, models, references" and
// "Analysis, without being asked"; analysis/views.h).
#include "routes/api_schemas.h"

namespace ambdiag::server::detail {

using namespace schema;

void add_analysis_schemas(RouteTable& t) {
  const json reference = object({{"runs", array(string())}, {"status", one_of({"active", "proposed"})}},
                                {{"version", integer()}, {"created_at", time()}, {"created_by", string()}});
  t.add_schema("Reference", reference);
  t.add_schema("Pump", object({{"pump_id", string()}, {"health", health()}, {"active_alarms", integer()}},
                              {{"n_runs", integer()},
                               {"model_version", integer()},
                               {"reference", ref("Reference")},
                               {"last_run_id", string()},
                               {"last_analysis", object({{"run_id", string()}, {"job_id", integer()}, {"finished_at", time()}},
                                                        {{"detected", boolean()}, {"ratio", number()}, {"fault", string()}})}}));
  // cli.md's fit: one identified mode, labelled where it pairs with a model mode.
  t.add_schema("FittedMode", object({{"f_hz", number()},
                                     {"zeta", number()},
                                     {"f_sd_hz", number()},
                                     {"zeta_sd", number()},
                                     {"direction", one_of({"radial", "axial"})},
                                     {"whirl", string()}},
                                    {{"label", string()},
                                     {"model_f_hz", number()},
                                     {"model_zeta", number()},
                                     {"outputs", array(string())},
                                     {"inputs", array(string())},
                                     {"peak_snr", number()},
                                     {"stable_orders", integer()}}));
  const json detection = object({{"detected", boolean()}, {"statistic", number()}, {"threshold", number()}, {"false_alarm_rate", number()}},
                                {{"ratio", number()}, {"dof", number()}, {"p_value", number()}, {"operating", object({})}});
  // cli.md's diagnose: the faults ranked, each with its fitted parameters
  // ("unknown" when no fault model explains the change).
  const json fault = object({{"fault", string()}, {"score", number()}, {"parameters", map_of(any())}},
                            {{"location", object({})}, {"chi2", number()}, {"bic", number()}, {"nrmse", number()}, {"reason", string()}});
  const json diagnosis = object({{"detected", boolean()},
                                 {"statistic", number()},
                                 {"threshold", number()},
                                 {"symptoms", array(object({{"kind", string()}}))},
                                 {"faults", array(fault)}},
                                {{"dof", number()}, {"p_value", number()}, {"fit", object({})}, {"not_assessed", array(object({{"fault", string()}}))}});
  t.add_schema("Analysis", object({{"run_id", string()},
                                   {"pump_id", string()},
                                   {"status", one_of({"waiting", "queued", "running", "done", "failed"})}},
                                  {{"progress", number()},
                                   {"error", string()},
                                   {"reason", string()},
                                   {"model_version", integer()},
                                   {"reference_version", integer()},
                                   {"job_id", integer()},
                                   {"attempts", integer()},
                                   {"modes", array(ref("FittedMode"))},
                                   {"nrmse", number()},
                                   {"detection", nullable(detection)},
                                   {"diagnosis", nullable(diagnosis)},
                                   {"files", map_of(string())}}));
  t.add_schema("Job", object({{"job_id", integer()},
                              {"kind", string()},
                              {"pump_id", string()},
                              {"status", job_status()},
                              {"progress", number()},
                              {"attempts", integer()},
                              {"created_at", time()}},
                             {{"run_id", string()},
                              {"model_version", integer()},
                              {"reference_version", integer()},
                              {"started_at", time()},
                              {"finished_at", time()},
                              {"error", string()},
                              {"depends_on", integer()},
                              {"worker", string()},
                              {"lease_expires_at", time()},
                              {"result", any()},
                              {"files", map_of(string())}}));
}

}  // namespace ambdiag::server::detail
