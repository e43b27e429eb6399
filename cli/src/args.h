// A small command-line parser for the ambdiag subcommands: positional
// arguments, `--name value` options, `--flag` switches and `-o FILE`.
// Anything not declared is a usage error (exit 2).
#pragma once

#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace ambdiag::cli {

// Wrong command line: exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Args {
 public:
  // `options` take a value, `flags` do not; names include the dashes.
  Args(const std::vector<std::string>& argv, const std::set<std::string>& options, const std::set<std::string>& flags,
       const std::set<std::string>& multi = {});

  const std::vector<std::string>& positional() const { return positional_; }
  bool flag(const std::string& name) const { return flags_.count(name) > 0; }
  std::optional<std::string> option(const std::string& name) const;
  // The option's value; throws UsageError "missing NAME VALUE_NAME" without it.
  std::string required(const std::string& name, const std::string& value_name) const;
  std::vector<std::string> values(const std::string& name) const;  // repeated / multi-valued options
  // Numeric option; throws UsageError naming the option if not a number.
  std::optional<double> number(const std::string& name) const;
  // Exactly `n` positional arguments, or a UsageError naming what is missing.
  void expect_positional(size_t n, const std::string& what) const;

 private:
  std::vector<std::string> positional_;
  std::set<std::string> flags_;
  std::map<std::string, std::vector<std::string>> options_;
};

}  // namespace ambdiag::cli
