#pragma once
/// "Did you mean": after a parse error, the nearest subcommand or option name
/// to what was typed (blot_main.cpp prints it under CLI11's message).
#include <CLI/CLI.hpp>

#include <string>

namespace blot::cli {

/// A line such as "did you mean 'run'?" for the first unknown subcommand or
/// option in argv, "" when nothing is close. Hidden (testing-only) options are
/// never suggested.
std::string suggestion(const CLI::App& app, int argc, const char* const* argv);

}  // namespace blot::cli
