// Runs the real ambdiag binary (AMBDIAG_CLI) for the CLI tests: exit code,
// stdout and stderr.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include "test_support.h"

namespace ambdiag::testing {

struct CliResult {
  int code = -1;
  std::string out, err;
};

// `args` are shell-quoted by the caller.
inline CliResult run_cli(const std::string& args) {
  // Not scratch_dir(): that would empty the test's own folder.
  const std::string err_path = write_scratch("stderr.txt", "").string();
  const std::string cmd = std::string(AMBDIAG_CLI) + " " + args + " 2>" + err_path;
  CliResult r;
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream e(err_path);
  r.err.assign(std::istreambuf_iterator<char>(e), std::istreambuf_iterator<char>());
  return r;
}

}  // namespace ambdiag::testing
