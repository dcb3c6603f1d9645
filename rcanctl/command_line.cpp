#include "command_line.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <ostream>
#include <vector>

#include "exit_codes.hpp"

namespace rcand::rcanctl {

std::unique_ptr<CLI::App> make_command_app(std::string_view words, std::string_view description, std::string_view footer) {
  auto app = std::make_unique<CLI::App>(std::string(description), std::string(words));
  app->set_help_flag("-h,--help", "print this help and exit");
  app->fallthrough();  // `nav go --distance 1 --port 8001`: the connection options after the action's name
  if (!footer.empty()) app->footer(std::string(footer));
  return app;
}

std::optional<int> parse_command_line(CLI::App& app, std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes the words last first
  try {
    app.parse(reversed);
  } catch (const CLI::CallForHelp&) {
    out << app.help();
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    // The innermost subcommand named on the line: its --help is the one to read.
    std::string words = app.get_name();
    for (const CLI::App* named = &app; !named->get_subcommands().empty();) {
      named = named->get_subcommands().front();
      words += " " + named->get_name();
    }
    std::string what = e.what();
    // CLI11 lists unexpected words last first; name the first one as the operator wrote it.
    if (const auto extra = app.remaining(true); dynamic_cast<const CLI::ExtrasError*>(&e) != nullptr && !extra.empty())
      what =
          extra.front().starts_with("-") ? "unknown option '" + extra.front() + "'" : "unexpected word '" + extra.front() + "'";
    // `rcanctl nav sideways`: CLI11 says a subcommand is required; the operator needs to hear which word it did not know.
    const auto actions = app.get_subcommands([](const CLI::App*) { return true; });
    if (dynamic_cast<const CLI::RequiredError*>(&e) != nullptr && !actions.empty() && words == app.get_name() && !args.empty() &&
        !args.front().starts_with("-")) {
      what = "unknown action '" + args.front() + "' (one of:";
      for (const CLI::App* action : actions) what += " " + action->get_name();
      what += ")";
    }
    std::replace(what.begin(), what.end(), '\n', ' ');
    err << words << ": " << what << " (see " << words << " --help)\n";
    return kExitUsage;
  }
  return std::nullopt;
}

int usage_error(const CLI::App& app, std::string_view what, std::ostream& err) {
  err << app.get_name() << ": " << what << " (see " << app.get_name() << " --help)\n";
  return kExitUsage;
}

CLI::Validator finite_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double value = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (ec != std::errc{} || end != text.data() + text.size() || !std::isfinite(value))
          return "must be a number, got '" + text + "'";
        return {};
      },
      "NUMBER");
}

}  // namespace rcand::rcanctl
