// The tests' JSON Schema validator refuses what it must: a missing required
// key, a wrong type, a value outside an enum, an item or a $ref target that
// breaks its schema, an unresolved $ref; and accepts extra keys, null where
// the type allows it, integers as numbers.
#include "json_schema_check.h"

#include <gtest/gtest.h>

namespace ambdiag::testing {
namespace {

using nlohmann::json;

const json kDocument = {
    {"components",
     {{"schemas",
       {{"Pump",
         {{"type", "object"},
          {"required", {"pump_id", "health"}},
          {"properties",
           {{"pump_id", {{"type", "string"}}},
            {"health", {{"type", "string"}, {"enum", {"ok", "warning", "alarm", "unknown"}}}},
            {"model_version", {{"type", {"integer", "null"}}}},
            {"files", {{"type", "object"}, {"additionalProperties", {{"type", "string"}}}}}}}}}}}}}};
const json kList = {{"type", "object"},
                    {"required", {"pumps"}},
                    {"properties", {{"pumps", {{"type", "array"}, {"items", {{"$ref", "#/components/schemas/Pump"}}}}}}}};

std::vector<std::string> check(const json& v, const json& s = kList) { return schema_violations(v, s, kDocument); }

TEST(JsonSchemaCheck, AcceptsAConformingAnswerWithMoreKeysThanDocumented) {
  EXPECT_TRUE(check({{"pumps", {{{"pump_id", "P-1"}, {"health", "ok"}, {"model_version", 3}, {"extra", true}},
                                {{"pump_id", "P-2"}, {"health", "unknown"}, {"model_version", nullptr}}}}})
                  .empty());
  EXPECT_TRUE(check(2.0, {{"type", "integer"}}).empty()) << "an integral number is an integer";
  EXPECT_TRUE(check(2, {{"type", "number"}}).empty());
}

TEST(JsonSchemaCheck, RefusesAMissingRequiredKeyNamingItAndWhere) {
  const auto v = check({{"pumps", {{{"pump_id", "P-1"}}}}});
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0], "/pumps/0: lacks required key \"health\"");
  EXPECT_EQ(check(json::object()).size(), 1u);
}

TEST(JsonSchemaCheck, RefusesAWrongType) {
  const auto v = check({{"pumps", {{{"pump_id", 101}, {"health", "ok"}}}}});
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NE(v[0].find("/pumps/0/pump_id: is number"), std::string::npos) << v[0];
  EXPECT_FALSE(check({{"pumps", {{{"pump_id", "P"}, {"health", "ok"}, {"model_version", 1.5}}}}}).empty());
  EXPECT_FALSE(check({{"pumps", "P-1"}}).empty());
  EXPECT_FALSE(check({{"pumps", {{{"pump_id", "P"}, {"health", "ok"}, {"files", {{"a", 1}}}}}}}).empty())
      << "additionalProperties' schema applies to each value";
}

TEST(JsonSchemaCheck, RefusesAValueOutsideItsEnum) {
  const auto v = check({{"pumps", {{{"pump_id", "P-1"}, {"health", "fine"}}}}});
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NE(v[0].find("/pumps/0/health: \"fine\" is not one of"), std::string::npos) << v[0];
}

TEST(JsonSchemaCheck, AnyOfNeedsOneAlternativeAndAnUnknownRefIsAViolation) {
  const json either = {{"anyOf", {{{"type", "string"}}, {{"type", "null"}}}}};
  EXPECT_TRUE(check(nullptr, either).empty());
  EXPECT_TRUE(check("x", either).empty());
  EXPECT_EQ(check(1, either).size(), 1u);
  const auto v = check({{"a", 1}}, {{"$ref", "#/components/schemas/Nope"}});
  ASSERT_EQ(v.size(), 1u);
  EXPECT_NE(v[0].find("unresolved $ref"), std::string::npos);
}

}  // namespace
}  // namespace ambdiag::testing
