#include "args.h"

#include <cmath>
#include <cstdlib>

namespace ambdiag::cli {

Args::Args(const std::vector<std::string>& argv, const std::set<std::string>& options,
           const std::set<std::string>& flags, const std::set<std::string>& multi) {
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.size() > 1 && a[0] == '-' && !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      if (flags.count(a)) {
        flags_.insert(a);
      } else if (options.count(a)) {
        if (i + 1 >= argv.size()) throw UsageError(a + ": needs a value");
        options_[a].push_back(argv[++i]);
      } else if (multi.count(a)) {
        // Takes every following argument up to the next option.
        size_t taken = 0;
        while (i + 1 < argv.size() && !(argv[i + 1].size() > 1 && argv[i + 1].rfind("--", 0) == 0)) {
          options_[a].push_back(argv[++i]);
          ++taken;
        }
        if (taken == 0) throw UsageError(a + ": needs at least one value");
      } else {
        throw UsageError("unknown option " + a + " (see --help)");
      }
    } else {
      positional_.push_back(a);
    }
  }
}

std::optional<std::string> Args::option(const std::string& name) const {
  auto it = options_.find(name);
  if (it == options_.end()) return std::nullopt;
  if (it->second.size() > 1) throw UsageError(name + ": given more than once");
  return it->second.front();
}

std::vector<std::string> Args::values(const std::string& name) const {
  auto it = options_.find(name);
  return it == options_.end() ? std::vector<std::string>{} : it->second;
}

std::optional<double> Args::number(const std::string& name) const {
  const auto v = option(name);
  if (!v) return std::nullopt;
  char* end = nullptr;
  const double d = std::strtod(v->c_str(), &end);
  if (end == v->c_str() || *end != '\0' || !std::isfinite(d)) throw UsageError(name + ": \"" + *v + "\" is not a number");
  return d;
}

void Args::expect_positional(size_t n, const std::string& what) const {
  if (positional_.size() < n) throw UsageError("missing " + what);
  if (positional_.size() > n) throw UsageError("unexpected argument \"" + positional_[n] + "\"");
}

std::string Args::required(const std::string& name, const std::string& value_name) const {
  const auto v = option(name);
  if (!v) throw UsageError("missing " + name + " " + value_name);
  return *v;
}

}  // namespace ambdiag::cli
