// The subcommand table of the `ambdiag` CLI (../shared/specs/cli.md).
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace ambdiag::cli {

// Exit codes of the CLI contract.
inline constexpr int kExitOk = 0;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitBadInput = 3;

struct Command {
  std::vector<std::string> path;  // e.g. {"model", "modes"}
  std::string summary;            // one line for the command list
  std::string help;               // full --help text
  std::function<int(const std::vector<std::string>&)> run;  // arguments after the path
};

// Each subcommand family registers itself here (model_commands.cc, ...).
std::vector<Command> model_commands();
std::vector<Command> convert_commands();
std::vector<Command> estimate_commands();
std::vector<Command> fit_commands();
std::vector<Command> serve_commands();
std::vector<Command> db_commands();
std::vector<Command> token_commands();
std::vector<Command> explain_commands();
std::vector<Command> diagnose_commands();

// Writes progress "label: done/total" on stderr, at most every 200 ms and at
// the end; silent when stderr is not a terminal unless forced by
// AMBDIAG_PROGRESS=1.
class Progress {
 public:
  Progress(std::string label, long total);
  void update(long done);
  void finish();

 private:
  std::string label_;
  long total_;
  long last_ms_ = -1000;
  bool enabled_;
};

}  // namespace ambdiag::cli
