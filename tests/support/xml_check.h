// A minimal XML well-formedness check for generated documents (SVG): tags
// balance and nest, there is one root element, attribute values are quoted,
// and text and attributes hold no raw '<' and no '&' outside an entity.
// Not a validating parser: no DTDs, CDATA or comments (we never write them).
#pragma once

#include <cctype>
#include <string>
#include <string_view>
#include <vector>

namespace ambdiag::testing {

namespace xml_detail {

inline bool valid_entities(std::string_view s) {
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<') return false;
    if (s[i] != '&') continue;
    const size_t semi = s.find(';', i);
    if (semi == std::string_view::npos) return false;
    const std::string_view e = s.substr(i + 1, semi - i - 1);
    if (e != "amp" && e != "lt" && e != "gt" && e != "quot" && e != "apos" &&
        !(e.size() > 1 && e[0] == '#')) {
      return false;
    }
    i = semi;
  }
  return true;
}

}  // namespace xml_detail

// Returns an empty string if `doc` is well formed, else what is wrong.
// `elements` (optional) receives the number of elements.
inline std::string xml_problem(std::string_view doc, int* elements = nullptr) {
  std::vector<std::string> stack;
  int count = 0, roots = 0;
  size_t i = 0;
  auto name_at = [&](size_t& p) {
    const size_t b = p;
    while (p < doc.size() && (std::isalnum(static_cast<unsigned char>(doc[p])) || doc[p] == '-' ||
                              doc[p] == ':' || doc[p] == '_' || doc[p] == '.'))
      ++p;
    return std::string(doc.substr(b, p - b));
  };
  auto skip_ws = [&](size_t& p) {
    while (p < doc.size() && std::isspace(static_cast<unsigned char>(doc[p]))) ++p;
  };
  if (doc.substr(0, 5) == "<?xml") {
    i = doc.find("?>");
    if (i == std::string_view::npos) return "unterminated XML declaration";
    i += 2;
  }
  while (i < doc.size()) {
    const size_t lt = doc.find('<', i);
    const std::string_view text =
        doc.substr(i, lt == std::string_view::npos ? std::string_view::npos : lt - i);
    if (!xml_detail::valid_entities(text)) return "bad text near offset " + std::to_string(i);
    if (stack.empty() && text.find_first_not_of(" \t\r\n") != std::string_view::npos) {
      return "text outside the root element at offset " + std::to_string(i);
    }
    if (lt == std::string_view::npos) break;
    size_t p = lt + 1;
    const bool closing = p < doc.size() && doc[p] == '/';
    if (closing) ++p;
    const std::string name = name_at(p);
    if (name.empty()) return "tag without a name at offset " + std::to_string(lt);
    if (closing) {
      skip_ws(p);
      if (p >= doc.size() || doc[p] != '>') return "bad closing tag </" + name;
      if (stack.empty() || stack.back() != name) return "</" + name + "> does not match the open element";
      stack.pop_back();
      i = p + 1;
      continue;
    }
    // Attributes: name="value" or name='value'.
    bool self_closing = false;
    for (;;) {
      skip_ws(p);
      if (p >= doc.size()) return "unterminated tag <" + name;
      if (doc[p] == '>') break;
      if (doc[p] == '/' && p + 1 < doc.size() && doc[p + 1] == '>') {
        self_closing = true;
        ++p;
        break;
      }
      const std::string attr = name_at(p);
      if (attr.empty()) return "bad attribute in <" + name;
      skip_ws(p);
      if (p >= doc.size() || doc[p] != '=') return "attribute " + attr + " without a value in <" + name;
      ++p;
      skip_ws(p);
      if (p >= doc.size() || (doc[p] != '"' && doc[p] != '\'')) return "unquoted attribute " + attr;
      const char q = doc[p];
      const size_t end = doc.find(q, p + 1);
      if (end == std::string_view::npos) return "unterminated attribute " + attr;
      if (!xml_detail::valid_entities(doc.substr(p + 1, end - p - 1)))
        return "bad attribute value of " + attr;
      p = end + 1;
    }
    ++count;
    if (stack.empty()) ++roots;
    if (!self_closing) stack.push_back(name);
    i = p + 1;
  }
  if (!stack.empty()) return "<" + stack.back() + "> is never closed";
  if (roots != 1) return "expected one root element, found " + std::to_string(roots);
  if (elements) *elements = count;
  return "";
}

}  // namespace ambdiag::testing
