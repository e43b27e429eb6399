// The `ambdiag` command line (../shared/specs/cli.md): dispatches to the
// subcommands and maps failures to the contract's exit codes.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "ambdiag/core/error.h"
#include "ambdiag/core/process_memory.h"
#include "args.h"
#include "command.h"

namespace {

using ambdiag::cli::Command;

std::vector<Command> all_commands() {
  std::vector<Command> all;
  for (auto&& family : {ambdiag::cli::model_commands(), ambdiag::cli::convert_commands(),
                       ambdiag::cli::fit_commands(), ambdiag::cli::estimate_commands(),
                       ambdiag::cli::serve_commands(), ambdiag::cli::db_commands(),
                       ambdiag::cli::token_commands(),
                       ambdiag::cli::explain_commands(),
                       ambdiag::cli::diagnose_commands()})
    all.insert(all.end(), family.begin(), family.end());
  return all;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
  return s;
}

void print_usage(const std::vector<Command>& cmds, const std::vector<std::string>& prefix) {
  std::printf("usage: ambdiag %s<command> [options]\n\n", prefix.empty() ? "" : (join(prefix) + " ").c_str());
  std::printf("ambdiag: model-based fault diagnosis of rotors in active magnetic bearings.\n\ncommands:\n");
  for (const auto& c : cmds) {
    if (!std::equal(prefix.begin(), prefix.end(), c.path.begin())) continue;
    std::printf("  %-18s %s\n", join(c.path).c_str(), c.summary.c_str());
  }
  std::printf("\n'ambdiag COMMAND --help' for a command's options. Exit codes: 0 ok, 2 usage error, 3 bad input.\n");
}

}  // namespace

int main(int argc, char** argv) {
  ambdiag::retain_freed_memory();
  const std::vector<std::string> args(argv + 1, argv + argc);
  const auto cmds = all_commands();
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    print_usage(cmds, {});
    return args.empty() ? ambdiag::cli::kExitUsage : ambdiag::cli::kExitOk;
  }
  if (args[0] == "--version") {
    std::printf("ambdiag 0.1.0\n");
    return 0;
  }
  // Longest command path that matches the arguments.
  const Command* match = nullptr;
  for (const auto& c : cmds) {
    if (c.path.size() <= args.size() && std::equal(c.path.begin(), c.path.end(), args.begin()) &&
        (!match || c.path.size() > match->path.size())) {
      match = &c;
    }
  }
  if (!match) {
    const bool family = std::any_of(cmds.begin(), cmds.end(), [&](const Command& c) { return c.path[0] == args[0]; });
    if (family && (args.size() == 1 || args[1] == "--help" || args[1] == "-h")) {
      print_usage(cmds, {args[0]});
      return args.size() == 1 ? ambdiag::cli::kExitUsage : ambdiag::cli::kExitOk;
    }
    std::fprintf(stderr, "ambdiag: unknown command '%s' (see 'ambdiag --help')\n",
                 join(std::vector<std::string>(args.begin(), args.begin() + (family && args.size() > 1 ? 2 : 1))).c_str());
    return ambdiag::cli::kExitUsage;
  }
  const std::vector<std::string> rest(args.begin() + static_cast<long>(match->path.size()), args.end());
  if (std::find(rest.begin(), rest.end(), "--help") != rest.end() || std::find(rest.begin(), rest.end(), "-h") != rest.end()) {
    std::printf("%s", match->help.c_str());
    return ambdiag::cli::kExitOk;
  }
  try {
    return match->run(rest);
  } catch (const ambdiag::cli::UsageError& e) {
    std::fprintf(stderr, "ambdiag %s: %s\n(see 'ambdiag %s --help')\n", join(match->path).c_str(), e.what(),
                 join(match->path).c_str());
    return ambdiag::cli::kExitUsage;
  } catch (const ambdiag::InputError& e) {
    std::fprintf(stderr, "ambdiag %s: bad input: %s\n", join(match->path).c_str(), e.what());
    return ambdiag::cli::kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ambdiag %s: internal error: %s\n", join(match->path).c_str(), e.what());
    return 1;
  }
}
