// rcanctl's one way to read a command line: every subcommand declares its options on a CLI11 app (so --help lists
// every option, generated from the same table that parses them), and every parse ends the same way: --help printed
// with exit 0, or one line naming what is wrong with exit 2 and nothing sent (exit_codes.hpp).
#pragma once

#include <CLI/CLI.hpp>

#include <iosfwd>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace rcand::rcanctl {

// An app for `rcanctl <words>` ("rcanctl nav"): the name in errors and help, the description above the options and
// the footer (exit codes, defaults, examples) under them. Options of the app may follow its subcommands' names.
std::unique_ptr<CLI::App> make_command_app(std::string_view words, std::string_view description, std::string_view footer = {});

// Parses `args` (the words after the subcommand's name): nullopt to go on, else the exit code after --help
// (printed on `out`, 0) or a usage error (one line on `err`, 2).
std::optional<int> parse_command_line(CLI::App& app, std::span<const std::string> args, std::ostream& out, std::ostream& err);

// A usage error found after the parse (a missing combination, a bad value): one line on `err`, returns 2.
int usage_error(const CLI::App& app, std::string_view what, std::ostream& err);

// Rejects a value that is not a finite number with one clear line ("--linear must be a number, got 'fast'").
CLI::Validator finite_number();

}  // namespace rcand::rcanctl
