// `ambdiag token add|list|revoke`: the API tokens of a historian
// (../shared/specs/rest.md, "Who may do what"). Each opens its own write
// connection, so they work while `ambdiag serve` runs on the same file
// (WAL, busy timeout) and take effect on the server's next request.
#include <cstdio>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/historian.h"
#include "args.h"
#include "command.h"

namespace ambdiag::cli {

namespace {

int run_token_add(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db", "--role", "--name"}, {"--json"});
  args.expect_positional(0, "nothing (the name goes in --name)");
  const auto name = args.option("--name");
  if (!name) throw UsageError("missing --name NAME");
  const auto role_text = args.option("--role");
  if (!role_text) throw UsageError("missing --role viewer|operator|engineer|admin");
  const auto role = storage::role_from(*role_text);
  if (!role) throw UsageError("--role: '" + *role_text + "' is not viewer, operator, engineer or admin");
  auto h = storage::Historian::open(args.required("--db", "FILE"));
  const std::string token = h.add_token(*name, *role);
  if (args.flag("--json")) {
    std::cout << nlohmann::json{{"name", *name}, {"role", storage::to_string(*role)}, {"token", token}}.dump(2)
              << "\n";
  } else {
    std::printf("%s\n", token.c_str());
    std::fprintf(stderr, "token '%s' (%s) created; it is shown this once, only its hash is stored\n", name->c_str(),
                 storage::to_string(*role).c_str());
  }
  return kExitOk;
}

int run_token_list(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db"}, {"--json"});
  args.expect_positional(0, "nothing");
  // A writer: creates the schema where missing, like add and revoke.
  auto h = storage::Historian::open(args.required("--db", "FILE"));
  const auto tokens = h.list_tokens();
  if (args.flag("--json")) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& t : tokens) {
      nlohmann::json j = {{"name", t.name}, {"role", storage::to_string(t.role)}, {"created_at", t.created_at}};
      if (t.revoked_at) j["revoked_at"] = *t.revoked_at;
      list.push_back(std::move(j));
    }
    std::cout << nlohmann::json{{"tokens", list}}.dump(2) << "\n";
    return kExitOk;
  }
  for (const auto& t : tokens)
    std::printf("%-32s %-9s created %s%s\n", t.name.c_str(), storage::to_string(t.role).c_str(), t.created_at.c_str(),
                t.revoked_at ? (", revoked " + *t.revoked_at).c_str() : "");
  return kExitOk;
}

int run_token_revoke(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db"}, {});
  args.expect_positional(1, "NAME");
  const std::string& name = args.positional()[0];
  auto h = storage::Historian::open(args.required("--db", "FILE"));
  if (!h.revoke_token(name)) throw InputError("no active token named '" + name + "'");
  std::fprintf(stderr, "token '%s' revoked\n", name.c_str());
  return kExitOk;
}

}  // namespace

std::vector<Command> token_commands() {
  return {
      {{"token", "add"},
       "create an API token and print it once",
       "usage: ambdiag token add --db FILE --role ROLE --name NAME [--json]\n\n"
       "Creates a token for NAME (1 to 64 of A-Z a-z 0-9 . _ @ -) with ROLE: viewer (every GET),\n"
       "operator (alarms), engineer (models, references, analyses) or admin (tokens). Prints the\n"
       "token on stdout ({\"name\", \"role\", \"token\"} with --json); it is shown this once, the\n"
       "historian keeps only its SHA-256. Works while a server runs on FILE; creates FILE if missing.\n"
       "Exit 2 for a bad role, 3 for a bad or taken name.\n",
       run_token_add},
      {{"token", "list"},
       "the API tokens: names, roles, when created and revoked",
       "usage: ambdiag token list --db FILE [--json]\n\n"
       "Names, roles, created_at and revoked_at; never a token or its hash.\n",
       run_token_list},
      {{"token", "revoke"},
       "revoke an API token by name",
       "usage: ambdiag token revoke --db FILE NAME\n\n"
       "The token stops working on the server's next request. Exit 3 when NAME has no active token.\n",
       run_token_revoke},
  };
}

}  // namespace ambdiag::cli
