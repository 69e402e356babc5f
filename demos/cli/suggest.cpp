// "Did you mean" for mistyped subcommands and options (suggest.h). CLI11 2.1
// reports unknown arguments (ExtrasError) but suggests nothing; this compares
// what was typed with the names the app itself registered.
#include "suggest.h"

#include <algorithm>
#include <string>
#include <vector>

namespace blot::cli {
namespace {

/// Levenshtein distance (insertions, deletions, substitutions).
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// The closest name within a third of the typed length (at least 2, at most 3 edits), or "".
std::string closest(const std::string& typed, const std::vector<std::string>& names) {
  const std::size_t limit = std::clamp<std::size_t>(typed.size() / 3, 2, 3);
  std::string best;
  std::size_t bestDistance = limit + 1;
  for (const std::string& name : names) {
    const std::size_t d = editDistance(typed, name);
    if (d < bestDistance) {
      bestDistance = d;
      best = name;
    }
  }
  return best;
}

/// The visible long option names of `app` ("--out", ...).
std::vector<std::string> optionNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::Option* option : app.get_options()) {
    if (option->get_group().empty()) continue;  // hidden
    for (const std::string& name : option->get_lnames()) names.push_back("--" + name);
  }
  return names;
}

}  // namespace

std::string suggestion(const CLI::App& app, int argc, const char* const* argv) {
  std::vector<std::string> commands;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) commands.push_back(sub->get_name());

  const CLI::App* command = nullptr;
  for (int k = 1; k < argc; ++k) {
    const std::string arg = argv[k];
    if (arg.rfind("-", 0) == 0) {
      if (arg.rfind("--", 0) != 0) continue;
      const std::string name = arg.substr(0, arg.find('='));
      std::vector<std::string> known = optionNames(app);
      if (command != nullptr) {
        const std::vector<std::string> own = optionNames(*command);
        known.insert(known.end(), own.begin(), own.end());
      }
      if (std::find(known.begin(), known.end(), name) != known.end()) continue;
      const std::string near = closest(name, known);
      if (!near.empty()) return "did you mean '" + near + "'?";
      continue;
    }
    if (command == nullptr) {
      if (std::find(commands.begin(), commands.end(), arg) != commands.end()) {
        command = app.get_subcommand(arg);
        continue;
      }
      const std::string near = closest(arg, commands);
      if (!near.empty()) return "did you mean '" + near + "'?";
      // Nothing like one: CLI11 only says "A subcommand is required".
      std::string list;
      for (const std::string& c : commands) list += (list.empty() ? "" : ", ") + c;
      return "unknown command '" + arg + "' (expected one of: " + list + ")";
    }
  }
  return "";
}

}  // namespace blot::cli
