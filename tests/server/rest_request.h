// One request of a server test to a REST server on loopback, with a bearer
// token (none when empty): GET, PUT, or else POST, with a JSON body.
#pragma once

#include <httplib.h>

#include <string>

namespace ambdiag::server {

inline httplib::Result rest_request(int port, const std::string& method, const std::string& path, const std::string& token,
                                    const std::string& body = "") {
  httplib::Client c("127.0.0.1", port);
  c.set_read_timeout(10, 0);
  httplib::Headers h;
  if (!token.empty()) h.emplace("Authorization", "Bearer " + token);
  if (method == "GET") return c.Get(path, h);
  if (method == "PUT") return c.Put(path, h, body, "application/json");
  return c.Post(path, h, body, "application/json");
}

}  // namespace ambdiag::server
