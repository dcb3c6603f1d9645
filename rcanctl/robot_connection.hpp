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

#include "tls_options.hpp"

namespace rcand::rcanctl {

struct RobotOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 8000;
  std::string token;
  bool json = false;
  bool help = false;
  std::chrono::milliseconds timeout{5000};
  TlsOptions tls;  // --cacert/--cert/--key, https:// hosts (tls_options.hpp)
};

// Called for an option the common parser does not know: `next` yields its value (false after writing the error).
// Returns false when the option is unknown to the subcommand too.
using ExtraOption = std::function<bool(const std::string& option, const std::function<bool(std::string&)>& next)>;

// `text` as a whole integer in [low, high] (option values: ports, milliseconds); nullopt otherwise.
std::optional<int> parse_int(std::string_view text, int low, int high);

// The token in `path` without its line end; "" when the file cannot be read or is empty.
std::string read_token_file(const std::string& path);

// Parses `args`; on a usage error writes "<prefix>: what" to `err` and returns false. The token is required unless
// --help was given.
bool parse_robot_options(std::span<const std::string> args, std::string_view prefix, const ExtraOption& extra,
                         RobotOptions& options, std::ostream& err);

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
