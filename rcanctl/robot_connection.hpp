// One robot as an operator's command reaches it: the connection options every single-robot subcommand takes
// (--host, --port, --token/--token-file/$RCAND_TOKEN, --json, --timeout, the TLS options) and one request with its
// answer parsed.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "command_line.hpp"
#include "tls_options.hpp"

namespace rcand::rcanctl {

struct RobotOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 8000;
  std::string token;
  std::string token_file;
  bool json = false;
  std::chrono::milliseconds timeout{5000};
  TlsOptions tls;  // --cacert/--cert/--key, https:// hosts (tls_options.hpp)
};

// `text` as a whole integer in [low, high] (option values: ports, milliseconds); nullopt otherwise.
std::optional<int> parse_int(std::string_view text, int low, int high);

// The token in `path` without its line end; "" when the file cannot be read or is empty.
std::string read_token_file(const std::string& path);

// Declares the connection options on `app`: --host, --port, --token, --token-file, --json, --timeout, --cacert,
// --cert, --key (into `options`, which must outlive the parse).
void add_robot_options(CLI::App& app, RobotOptions& options);

// After the parse: HOST:PORT and https:// hosts, the TLS files, the token (--token-file, $RCAND_TOKEN; required).
// An error message, or "".
std::string finish_robot_options(RobotOptions& options);

// add_robot_options' options parsed and finished: nullopt to go on, else the exit code (0 after --help, 2 after one
// line naming the usage error).
std::optional<int> parse_robot_command(CLI::App& app, std::span<const std::string> args, RobotOptions& options);

struct RobotAnswer {
  int status = 0;       // 0: no answer (unreachable, timed out)
  nlohmann::json body;  // the parsed body (discarded when not JSON)
  std::string error;    // why it failed: the robot's "error" (with its code), or the transport's
  bool ok() const { return status >= 200 && status < 300; }
};

// One request with the bearer token; never throws.
RobotAnswer call_robot(const RobotOptions& options, std::string_view method, std::string_view target,
                       const nlohmann::json& body = nullptr);

// Prints `answer` as one JSON line (--json) or `human` (a table or a sentence) and returns the exit code: 0 when the
// robot answered 2xx, else 1 with the error on `err`.
int report(const RobotOptions& options, const RobotAnswer& answer, std::string_view what, const std::function<void()>& human,
           std::ostream& out, std::ostream& err);

}  // namespace rcand::rcanctl
