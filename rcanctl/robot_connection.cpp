#include "robot_connection.hpp"

#include <charconv>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <ostream>
#include <sstream>

#include "exit_codes.hpp"
#include "libs/http/client.hpp"
#include "local_names.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

}  // namespace

std::optional<int> parse_int(std::string_view text, int low, int high) {
  int value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size() || value < low || value > high) return std::nullopt;
  return value;
}

std::string read_token_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return {};
  std::stringstream text;
  text << in.rdbuf();
  std::string token = text.str();
  while (!token.empty() && (token.back() == '\n' || token.back() == '\r')) token.pop_back();
  return token;
}

void add_robot_options(CLI::App& app, RobotOptions& options) {
  app.add_option("--host", options.host,
                 "the robot: HOST, HOST:PORT or https://HOST[:PORT] (default 127.0.0.1; TLS with https://)");
  app.add_option("--port", options.port, "its port (default 8000)")->check(CLI::Range(1, 65535));
  app.add_option("--token", options.token, "the bearer token (or --token-file, or $RCAND_TOKEN)");
  app.add_option("--token-file", options.token_file, "a file holding the token");
  app.add_flag("--json", options.json, "print the robot's answer as one JSON line");
  app.add_option_function<int>(
         "--timeout", [&options](const int& ms) { options.timeout = std::chrono::milliseconds(ms); },
         "milliseconds to wait for the robot (default " + std::to_string(options.timeout.count()) + ")")
      ->check(CLI::Range(1, 600000));
  add_tls_options(app, options.tls);
}

std::string finish_robot_options(RobotOptions& options) {
  if (auto problem = finish_tls_options(options.tls, options.host, options.port); !problem.empty()) return problem;
  if (!options.token_file.empty()) {
    options.token = read_token_file(options.token_file);
    if (options.token.empty()) return "cannot read a token from --token-file " + options.token_file;
  }
  if (options.token.empty())
    if (const char* env = std::getenv("RCAND_TOKEN")) options.token = env;
  if (options.token.empty()) return "a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN";
  return {};
}

std::optional<int> parse_robot_command(CLI::App& app, std::span<const std::string> args, RobotOptions& options) {
  if (auto done = parse_command_line(app, args, std::cout, std::cerr)) return done;
  if (const auto problem = finish_robot_options(options); !problem.empty()) return usage_error(app, problem, std::cerr);
  return std::nullopt;
}

RobotAnswer call_robot(const RobotOptions& options, std::string_view method, std::string_view target, const json& body) {
  RobotAnswer answer;
  try {
    const auto response = http::request(
        address_of(options.host, options.timeout), options.port, method, target, body.is_null() ? std::string() : body.dump(),
        {{"Authorization", "Bearer " + options.token}}, options.timeout, client_tls(options.tls, options.host));
    answer.status = response.status;
    answer.body = json::parse(response.body, nullptr, false);
    if (answer.body.is_discarded()) answer.body = nullptr;
    if (!answer.ok()) {
      const bool described = answer.body.is_object() && answer.body.contains("error");
      const json& message = described ? answer.body["error"] : answer.body;
      answer.error = described ? answer.body.value("code", std::string("ERROR")) + ": " +
                                     (message.is_string() ? message.get<std::string>() : message.dump())
                               : "HTTP " + std::to_string(answer.status);
    }
  } catch (const std::exception& e) {
    answer.status = 0;
    answer.error = e.what();
  }
  return answer;
}

int report(const RobotOptions& options, const RobotAnswer& answer, std::string_view what, const std::function<void()>& human,
           std::ostream& out, std::ostream& err) {
  if (!answer.ok()) {
    if (options.json)
      out << json{{"ok", false}, {"http_status", answer.status ? json(answer.status) : json()}, {"error", answer.error}}.dump()
          << "\n";
    err << "rcanctl " << what << ": " << answer.error << "\n";
    return kExitFailure;
  }
  if (options.json) out << answer.body.dump(-1, ' ', false, json::error_handler_t::replace) << "\n";
  else human();
  return kExitOk;
}

}  // namespace rcand::rcanctl
