// Strict, bounded JSON parsing and bounded JSON text for messages.
//
// Design note: nlohmann parses iteratively, but a value nested 100,000 deep
// still breaks every recursive walk over it (dump(), a schema check, an
// error message), so the depth is refused in the parser callback, before the
// value exists. Duplicate keys are found in the same callback: one key set per
// open object.
#include <blot/stain/io/strict_json.h>

#include <cmath>
#include <set>
#include <vector>

namespace blot::stain {

nlohmann::json parseStrictJson(const std::string& text) {
  using Json = nlohmann::json;
  struct Level {
    bool object = false;
    std::string name;  // the key path of this container, for messages
    std::set<std::string> keys;
    std::string lastKey;
    std::size_t elements = 0;
  };
  std::vector<Level> open;
  const auto childName = [&]() -> std::string {
    if (open.empty()) return "";
    const Level& parent = open.back();
    const std::string base = parent.name;
    if (parent.object) return base.empty() ? parent.lastKey : base + "." + parent.lastKey;
    return base + "[" + std::to_string(parent.elements) + "]";
  };
  const auto countElement = [&](int depth) {
    if (!open.empty() && !open.back().object && depth == static_cast<int>(open.size())) ++open.back().elements;
  };
  const Json::parser_callback_t callback = [&](int depth, Json::parse_event_t event, Json& parsed) {
    switch (event) {
      case Json::parse_event_t::object_start:
      case Json::parse_event_t::array_start:
        if (depth >= kJsonMaxDepth)
          throw StrictJsonError("nested deeper than " + std::to_string(kJsonMaxDepth) + " arrays or objects (at " +
                                (childName().empty() ? std::string("the top level") : childName()) + ")");
        open.push_back({event == Json::parse_event_t::object_start, childName(), {}, {}, 0});
        break;
      case Json::parse_event_t::key: {
        Level& level = open.back();
        level.lastKey = parsed.get<std::string>();
        if (!level.keys.insert(level.lastKey).second)
          throw StrictJsonError((level.name.empty() ? level.lastKey : level.name + "." + level.lastKey) +
                                ": duplicate key (an object gives it twice; JSON readers disagree on which wins)");
        break;
      }
      case Json::parse_event_t::object_end:
      case Json::parse_event_t::array_end:
        open.pop_back();
        countElement(depth);
        break;
      case Json::parse_event_t::value:
        countElement(depth);
        break;
    }
    return true;
  };
  try {
    return Json::parse(text, callback);
  } catch (const Json::exception& e) {
    // Not only parse_error: a number too large for a double (1e999) is an
    // out_of_range from the same parse.
    throw StrictJsonError(std::string("invalid JSON: ") + e.what());
  }
}

namespace {

/// The first at most n bytes of s, shortened to a whole UTF-8 character: a
/// name of 101 "é" was echoed cut inside one (invalid UTF-8 on stderr).
std::string utf8Prefix(const std::string& s, std::size_t n) {
  if (s.size() <= n) return s;
  while (n > 0 && (static_cast<unsigned char>(s[n]) & 0xC0) == 0x80) --n;  // s[n] continues a character
  return s.substr(0, n);
}

void appendBrief(const nlohmann::json& value, std::size_t maxChars, int depth, std::string& out) {
  if (out.size() > maxChars) return;
  if (value.is_array() || value.is_object()) {
    const bool object = value.is_object();
    out += object ? '{' : '[';
    if (depth >= 4) {
      out += "...";
    } else {
      bool first = true;
      for (auto it = value.begin(); it != value.end() && out.size() <= maxChars; ++it) {
        if (!first) out += ',';
        first = false;
        if (object) out += nlohmann::json(it.key()).dump() + ':';
        appendBrief(*it, maxChars, depth + 1, out);
      }
    }
    out += object ? '}' : ']';
  } else if (value.is_string()) {
    const std::string& s = value.get_ref<const std::string&>();
    out += nlohmann::json(utf8Prefix(s, maxChars)).dump();
  } else {
    out += value.dump();
  }
}

}  // namespace

namespace {

bool hasNonFiniteNumber(const nlohmann::json& value) {
  if (value.is_number_float()) return !std::isfinite(value.get<double>());
  if (value.is_array() || value.is_object()) {
    for (const nlohmann::json& element : value)
      if (hasNonFiniteNumber(element)) return true;
  }
  return false;
}

void nameNonFiniteNumbers(nlohmann::json& value) {
  if (value.is_number_float()) {
    const double number = value.get<double>();
    if (std::isnan(number)) value = "NaN";
    else if (std::isinf(number)) value = number > 0 ? "Infinity" : "-Infinity";
  } else if (value.is_array() || value.is_object()) {
    for (nlohmann::json& element : value) nameNonFiniteNumbers(element);
  }
}

}  // namespace

std::string dumpJson(const nlohmann::json& value, int indent) {
  // The outputs are small and almost always finite: copied only when needed.
  if (!hasNonFiniteNumber(value)) return value.dump(indent);
  nlohmann::json named = value;
  nameNonFiniteNumbers(named);
  return named.dump(indent);
}

std::string briefJson(const nlohmann::json& value, std::size_t maxChars) {
  std::string text;
  appendBrief(value, maxChars, 0, text);
  if (text.size() > maxChars) text = utf8Prefix(text, maxChars > 3 ? maxChars - 3 : 0) + "...";
  return text;
}

}  // namespace blot::stain
