// Request paths: split into segments and percent-decoded one by one, so an
// encoded '/' (%2F) stays inside its segment.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace ambdiag::server::detail {

// Strict percent-decoding of one path segment ('+' stays '+'); nullopt for a
// malformed escape.
std::optional<std::string> url_decode_segment(const std::string& s);
// "/a/b%2Fc?x=1" -> {"a", "b/c"}; nullopt if the target is not an absolute
// path or holds a malformed escape.
std::optional<std::vector<std::string>> split_path(const std::string& target);

}  // namespace ambdiag::server::detail
