#include "json_fields.h"

#include <cmath>
#include <cstdint>
#include <limits>

#include "ambdiag/core/error.h"

namespace ambdiag::detail {

void JsonField::fail(const std::string& what) const { throw InputError(path_ + ": " + what); }

void JsonField::require_object() const {
  if (!value_->is_object()) fail("must be an object");
}

void JsonField::require_array() const {
  if (!value_->is_array()) fail("must be an array");
}

bool JsonField::has(const std::string& key) const {
  require_object();
  auto it = value_->find(key);
  return it != value_->end() && !it->is_null();
}

JsonField JsonField::at(const std::string& key) const {
  require_object();
  auto it = value_->find(key);
  const std::string sub = path_.empty() ? key : path_ + "." + key;
  if (it == value_->end() || it->is_null()) throw InputError(sub + ": missing");
  return JsonField(*it, sub);
}

std::optional<JsonField> JsonField::opt(const std::string& key) const {
  if (!has(key)) return std::nullopt;
  return at(key);
}

size_t JsonField::size() const {
  require_array();
  return value_->size();
}

JsonField JsonField::at(size_t i) const {
  require_array();
  if (i >= value_->size()) fail("index " + std::to_string(i) + " out of range");
  return JsonField((*value_)[i], path_ + "[" + std::to_string(i) + "]");
}

double JsonField::number() const {
  if (!value_->is_number()) fail("must be a number");
  const double v = value_->get<double>();
  if (!std::isfinite(v)) fail("must be finite");
  return v;
}

int64_t JsonField::integer() const {
  if (value_->is_number_unsigned() && value_->get<uint64_t>() > static_cast<uint64_t>(INT64_MAX)) fail("out of range");
  if (value_->is_number_integer()) return value_->get<int64_t>();
  if (value_->is_number_float()) {
    const double v = value_->get<double>();
    // Accept 3.0 but not 3.5 or values beyond int64.
    if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9.0e18) return static_cast<int64_t>(v);
  }
  fail("must be an integer");
}

std::string JsonField::string() const {
  if (!value_->is_string()) fail("must be a string");
  return value_->get<std::string>();
}

bool JsonField::boolean() const {
  if (!value_->is_boolean()) fail("must be true or false");
  return value_->get<bool>();
}

double JsonField::positive() const {
  const double v = number();
  if (!(v > 0.0)) fail("must be > 0");
  return v;
}

double JsonField::non_negative() const {
  const double v = number();
  if (!(v >= 0.0)) fail("must be >= 0");
  return v;
}

nlohmann::json parse_json_text(const std::string& text, const std::string& source) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(source + ": invalid JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  }
}

}  // namespace ambdiag::detail
