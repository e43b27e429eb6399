#include "serve_parts.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>

#include "args.h"

namespace ambdiag::cli {

std::vector<std::string> ServeParts::names() const {
  std::vector<std::string> out;
  if (ingest) out.push_back("ingest");
  if (analysis) out.push_back("analysis");
  if (rest) out.push_back("rest");
  return out;
}

std::string ServeParts::text() const {
  std::string s;
  for (const auto& n : names()) s += (s.empty() ? "" : ",") + n;
  return s;
}

ServeParts parse_serve_parts(const std::string& list) {
  ServeParts p{false, false, false};
  std::size_t at = 0;
  for (;;) {
    const auto comma = list.find(',', at);
    const std::string part = list.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
    bool* flag = part == "ingest" ? &p.ingest : part == "analysis" ? &p.analysis : part == "rest" ? &p.rest : nullptr;
    if (!flag)
      throw UsageError("--parts: " + (part.empty() ? std::string("an empty part") : "unknown part '" + part + "'") +
                       " in '" + list + "' (a comma-separated list of ingest, analysis, rest)");
    if (*flag) throw UsageError("--parts: part '" + part + "' given twice in '" + list + "'");
    *flag = true;
    if (comma == std::string::npos) return p;
    at = comma + 1;
  }
}

std::string serve_instance_name(const std::string& given) {
  if (given.empty()) {
    std::array<char, 256> host{};
    if (gethostname(host.data(), host.size() - 1) != 0) host = {'h', 'o', 's', 't'};
    std::string name = host.data();
    // A host name is letters, digits, '-' and '.' already; anything else goes.
    name.erase(std::remove_if(name.begin(), name.end(),
                              [](char c) { return !(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.'); }),
               name.end());
    return name.substr(0, 40) + ":" + std::to_string(getpid());
  }
  const bool ok = given.size() <= 64 && std::all_of(given.begin(), given.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == ':' || c == '@' || c == '-';
  });
  if (!ok) throw UsageError("--instance: '" + given.substr(0, 80) + "' must be 1 to 64 of A-Z a-z 0-9 . _ : @ -");
  return given;
}

}  // namespace ambdiag::cli
