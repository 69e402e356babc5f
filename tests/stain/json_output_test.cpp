// The JSON blot writes (run summaries, checkpoint records, mesh-info and
// figure reports) goes through stain::dumpJson: a number that is not finite
// is a named string, never nlohmann's `null` nor a bare NaN or Infinity.
#include <blot/stain/io/strict_json.h>

#include <gtest/gtest.h>

#include <limits>
#include <string>

namespace blot::stain {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(DumpJson, FiniteValuesAreWrittenAsNlohmannWritesThem) {
  const nlohmann::json value = {{"a", 1.5}, {"b", {1, -2.25e-300, 0.0}}, {"c", "text"}, {"d", nullptr}, {"e", true}};
  EXPECT_EQ(dumpJson(value), value.dump());
  EXPECT_EQ(dumpJson(value, 2), value.dump(2));
}

TEST(DumpJson, NonFiniteNumbersAreNamedStringsAtAnyDepth) {
  const nlohmann::json value = {{"nan", kNaN},
                                {"budget", {{"relative_error", kInf}, {"rates", {1.0, -kInf, kNaN}}}},
                                {"fine", 2.0}};
  const std::string text = dumpJson(value, 2);
  EXPECT_EQ(text.find("null"), std::string::npos) << text;
  const nlohmann::json back = nlohmann::json::parse(text);  // strict JSON: bare NaN or Infinity would not parse
  EXPECT_EQ(back["nan"], "NaN");
  EXPECT_EQ(back["budget"]["relative_error"], "Infinity");
  EXPECT_EQ(back["budget"]["rates"], nlohmann::json({1.0, "-Infinity", "NaN"}));
  EXPECT_EQ(back["fine"], 2.0);
  // The value given is not changed.
  EXPECT_TRUE(value["budget"]["relative_error"].is_number_float());
  // What nlohmann alone writes, which this replaces.
  EXPECT_NE(value.dump().find("null"), std::string::npos);
}

}  // namespace
}  // namespace blot::stain
