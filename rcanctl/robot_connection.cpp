#include "robot_connection.hpp"

#include <charconv>
#include <cstdlib>
#include <fstream>
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

bool parse_robot_options(std::span<const std::string> args, std::string_view prefix, const ExtraOption& extra,
                         RobotOptions& options, std::ostream& err) {
  std::string token_file;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    const auto next = [&](std::string& into) {
      if (i + 1 >= args.size()) {
        err << prefix << ": " << arg << " needs a value\n";
        return false;
      }
      into = args[++i];
      return true;
    };
    std::string text;
    if (arg == "--help" || arg == "-h") {
      options.help = true;
    } else if (arg == "--json") {
      options.json = true;
    } else if (arg == "--host") {
      if (!next(options.host)) return false;
    } else if (arg == "--port") {
      if (!next(text)) return false;
      const auto port = parse_int(text, 1, 65535);
      if (!port) {
        err << prefix << ": --port must be from 1 to 65535, got '" << text << "'\n";
        return false;
      }
      options.port = static_cast<std::uint16_t>(*port);
    } else if (arg == "--timeout") {
      if (!next(text)) return false;
      const auto ms = parse_int(text, 1, 600000);
      if (!ms) {
        err << prefix << ": --timeout must be milliseconds from 1 to 600000, got '" << text << "'\n";
        return false;
      }
      options.timeout = std::chrono::milliseconds(*ms);
    } else if (arg == "--token") {
      if (!next(options.token)) return false;
    } else if (arg == "--token-file") {
      if (!next(token_file)) return false;
      options.token = read_token_file(token_file);
      if (options.token.empty()) {
        err << prefix << ": cannot read a token from --token-file " << token_file << "\n";
        return false;
      }
    } else if (bool ok = true; parse_tls_option(arg, next, options.tls, ok)) {
      if (!ok) return false;
    } else if (!extra || !extra(arg, next)) {
      err << prefix << ": unknown option '" << arg << "' (see --help)\n";
      return false;
    }
  }
  if (options.help) return true;
  if (const auto problem = finish_tls_options(options.tls, options.host, options.port); !problem.empty()) {
    err << prefix << ": " << problem << "\n";
    return false;
  }
  if (options.token.empty())
    if (const char* env = std::getenv("RCAND_TOKEN")) options.token = env;
  if (options.token.empty()) {
    err << prefix << ": a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN\n";
    return false;
  }
  return true;
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
