// Typed access to a JSON document that names the field in every error
// (`shaft[3].od: must be a number`). Private to ambdiag_core.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace ambdiag::detail {

class JsonField {
 public:
  JsonField(const nlohmann::json& value, std::string path) : value_(&value), path_(std::move(path)) {}

  const std::string& path() const { return path_; }
  const nlohmann::json& raw() const { return *value_; }
  bool is_null() const { return value_->is_null(); }

  // Object access. `at` requires the key; `opt` treats absent and null alike.
  bool has(const std::string& key) const;
  JsonField at(const std::string& key) const;
  std::optional<JsonField> opt(const std::string& key) const;
  // Array access.
  size_t size() const;
  JsonField at(size_t i) const;

  void require_object() const;
  void require_array() const;
  double number() const;  // finite
  int64_t integer() const;
  std::string string() const;
  bool boolean() const;

  // Convenience: number with a bound check, message "must be > 0" etc.
  double positive() const;
  double non_negative() const;

  [[noreturn]] void fail(const std::string& what) const;

 private:
  const nlohmann::json* value_;
  std::string path_;
};

// Parses JSON text; throws InputError "<source>: invalid JSON at byte N: ...".
nlohmann::json parse_json_text(const std::string& text, const std::string& source);

}  // namespace ambdiag::detail
