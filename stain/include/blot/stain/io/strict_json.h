#pragma once
/// The one JSON parse of the scene and weave-pattern loaders: strict where
/// nlohmann is lenient (a duplicated key is an error instead of "last wins")
/// and bounded (nesting deeper than kJsonMaxDepth is refused while parsing,
/// so no later recursion over the value can exhaust the stack).
#include <nlohmann/json.hpp>

#include <stdexcept>
#include <string>

namespace blot::stain {

inline constexpr int kJsonMaxDepth = 64;  ///< arrays and objects nested deeper are refused

/// Not JSON, a duplicated key, or nested too deep; the message has no source
/// name (the caller adds it): "outputs.frames: duplicate key ...", ...
struct StrictJsonError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

nlohmann::json parseStrictJson(const std::string& text);

/// At most `maxChars` characters of a value's JSON text (then "..."), never
/// more than a few levels deep: safe for error messages on any value.
std::string briefJson(const nlohmann::json& value, std::size_t maxChars = 48);

/// The JSON text of every JSON file and report blot writes: value.dump(indent),
/// except that a number that is not finite, which nlohmann writes as `null`,
/// is written as the string "NaN", "Infinity" or "-Infinity" (what Python's
/// float() and JavaScript's Number() read back). So no output holds `null`,
/// `NaN` or `Infinity` where a number belongs.
std::string dumpJson(const nlohmann::json& value, int indent = -1);

}  // namespace blot::stain
