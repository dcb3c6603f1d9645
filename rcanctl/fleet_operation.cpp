#include "fleet_operation.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <optional>
#include <ostream>
#include <sstream>
#include <variant>

#include "libs/mdns/host_resolver.hpp"
#include "libs/swarm/broadcast_report.hpp"
#include "libs/swarm/fan_out.hpp"
#include "libs/swarm/node_selection.hpp"
#include "local_names.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

namespace swarm = rcand::swarm;
using nlohmann::json;

std::string_view operation_name(Operation op) {
  return op == Operation::Status ? "status" : op == Operation::Stop ? "stop" : "command";
}

// One node's row: the table's columns and the JSON object of --json.
struct Row {
  json object;
  bool ok = false;
};

std::string text_of(const json& value, const char* key, const std::string& fallback = "-") {
  if (!value.contains(key) || value[key].is_null()) return fallback;
  return value[key].is_string() ? value[key].get<std::string>() : value[key].dump();
}

Row status_row(const swarm::PeerResult& result) {
  json object{{"name", result.name},   {"address", result.address}, {"reachable", result.reachable}, {"ok", false},
              {"http_status", nullptr}, {"state", nullptr},          {"estopped", nullptr},           {"caps", json::array()},
              {"latency_ms", std::round(result.latency_ms * 1000.0) / 1000.0}, {"error", nullptr}};
  if (!result.reachable) {
    object["error"] = result.error;
    return {object, false};
  }
  object["http_status"] = result.status;
  const json body = json::parse(result.body, nullptr, false);
  if (result.status != 200 || !body.is_object()) {
    object["error"] = body.is_object() && body.contains("error") ? body["error"] : json("HTTP " + std::to_string(result.status));
    if (body.is_object() && body.contains("code")) object["code"] = body["code"];
    return {object, false};
  }
  for (const char* key : {"ruri", "version", "state", "estopped", "caps"})
    if (body.contains(key)) object[key] = body[key];
  // A robot that answers but reports a fault (a failed plugin or driver) is not "ok": scripts see exit 1.
  if (object["state"] == "error") {
    object["error"] = "the robot reports state error (rcanctl plugins names what failed)";
    return {object, false};
  }
  object["ok"] = true;
  return {object, true};
}

Row action_row(Operation op, const swarm::PeerResult& result) {
  json object = swarm::node_entry(result, op == Operation::Stop ? swarm::BroadcastKind::Stop : swarm::BroadcastKind::Command);
  object["reachable"] = result.reachable;
  const bool ok = object.value("ok", false);
  return {object, ok};
}

std::string result_text(Operation op, const json& row) {
  if (op == Operation::Status) return row.value("ok", false) ? "ok" : text_of(row, "error");
  if (!row.value("ok", false)) {
    const std::string code = text_of(row, "code", "");
    return "FAILED: " + (code.empty() ? "" : code + ": ") + text_of(row, "error");
  }
  if (!row.value("executed", true)) return "acknowledged, not executed (" + text_of(row, "reason", "no reason") + ")";
  return op == Operation::Stop ? "motors stopped" : "executed";
}

void print_table(Operation op, const std::vector<Row>& rows, std::ostream& out) {
  std::vector<std::vector<std::string>> cells{{"NAME", "ADDRESS", "REACHABLE", "STATE", "E-STOP", "CAPS", "LATENCY", "RESULT"}};
  for (const auto& row : rows) {
    const json& o = row.object;
    std::string state = text_of(o, "state");
    std::string estop = o.contains("estopped") && o["estopped"].is_boolean() ? (o["estopped"].get<bool>() ? "yes" : "no") : "-";
    if (op == Operation::Stop && o.value("executed", false)) {
      state = "estop";
      estop = "yes";
    }
    if (op == Operation::Command && o.value("reason", json()) == "estop_active") {
      state = "estop";
      estop = "yes";
    }
    std::string caps = "-";
    if (o.contains("caps") && o["caps"].is_array() && !o["caps"].empty()) {
      caps.clear();
      for (const auto& cap : o["caps"]) caps += (caps.empty() ? "" : ",") + (cap.is_string() ? cap.get<std::string>() : cap.dump());
    }
    std::ostringstream latency;
    latency << std::fixed << std::setprecision(1) << o.value("latency_ms", 0.0) << " ms";
    cells.push_back({text_of(o, "name"), o.value("address", std::string()).empty() ? "-" : text_of(o, "address"),
                     o.value("reachable", false) ? "yes" : "no", state, estop, caps, latency.str(), result_text(op, o)});
  }
  print_text_table(cells, out);
}

}  // namespace

bool parse_fleet_options(std::span<const std::string> args, Operation op, bool swarm_mode, FleetOptions& options, std::ostream& err) {
  const std::string prefix = std::string(swarm_mode ? "rcanctl swarm " : "rcanctl ") + std::string(operation_name(op)) + ": ";
  bool host_given = false, port_given = false;
  std::string token_file;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    auto value = [&](std::string& into) {
      if (i + 1 >= args.size()) {
        err << prefix << arg << " needs a value\n";
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
    } else if (arg == "--node") {
      if (!value(text)) return false;
      options.nodes.push_back(text);
    } else if (arg == "--tag" && swarm_mode) {
      if (!value(text)) return false;
      options.tags.push_back(text);
    } else if (arg == "--swarm") {
      if (!value(options.swarm_file)) return false;
    } else if (arg == "--timeout") {
      if (!value(text)) return false;
      const auto ms = parse_int(text, 1, 600000);
      if (!ms) {
        err << prefix << "--timeout must be milliseconds from 1 to 600000, got '" << text << "'\n";
        return false;
      }
      options.timeout_ms = *ms;
    } else if (arg == "--instruction" && op == Operation::Command) {
      if (!value(options.instruction)) return false;
    } else if (arg == "--host" && !swarm_mode) {
      if (!value(options.host)) return false;
      host_given = true;
    } else if (arg == "--port" && !swarm_mode) {
      if (!value(text)) return false;
      const auto port = parse_int(text, 1, 65535);
      if (!port) {
        err << prefix << "--port must be from 1 to 65535, got '" << text << "'\n";
        return false;
      }
      options.port = static_cast<std::uint16_t>(*port);
      port_given = true;
    } else if (arg == "--token" && !swarm_mode) {
      if (!value(options.token)) return false;
    } else if (arg == "--token-file" && !swarm_mode) {
      if (!value(token_file)) return false;
    } else if (bool ok = true; !swarm_mode && parse_tls_option(arg, value, options.tls, ok)) {
      if (!ok) return false;
      host_given = true;
    } else {
      err << prefix << "unknown option '" << arg << "' (see --help)\n";
      return false;
    }
  }
  if (options.help) return true;
  if (op == Operation::Command && options.instruction.empty()) {
    err << prefix << "--instruction \"...\" is required\n";
    return false;
  }
  if (!swarm_mode) {
    if (options.nodes.size() > 1) {
      err << prefix << "one --node at most (use rcanctl swarm for several)\n";
      return false;
    }
    if (!options.nodes.empty() && (host_given || port_given || !options.token.empty() || !token_file.empty())) {
      err << prefix << "--node takes address, token and TLS from the swarm file; drop --host/--port/--token/--cacert\n";
      return false;
    }
    if (const auto problem = finish_tls_options(options.tls, options.host, options.port); !problem.empty()) {
      err << prefix << problem << "\n";
      return false;
    }
    if (!token_file.empty()) {
      options.token = read_token_file(token_file);
      if (options.token.empty()) {
        err << prefix << "cannot read a token from --token-file " << token_file << "\n";
        return false;
      }
    }
    if (options.token.empty() && options.nodes.empty())
      if (const char* env = std::getenv("RCAND_TOKEN")) options.token = env;
    if (options.token.empty() && options.nodes.empty()) {
      err << prefix << "a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN\n";
      return false;
    }
  }
  return true;
}

bool swarm_targets(const FleetOptions& options, std::vector<swarm::SwarmNode>& targets, std::ostream& err) {
  swarm::SwarmRegistry registry;
  try {
    registry = swarm::load_swarm_file(options.swarm_file);
  } catch (const swarm::SwarmError& e) {
    err << "rcanctl: " << e.what() << "\n";
    return false;
  }
  for (const auto& warning : registry.warnings) err << "rcanctl: " << warning << "\n";
  auto chosen = swarm::select_nodes(registry, {options.nodes, options.tags});
  if (auto* failure = std::get_if<swarm::SelectionError>(&chosen)) {
    err << "rcanctl: " << options.swarm_file << ": " << failure->message << "\n";
    return false;
  }
  targets = std::get<std::vector<swarm::SwarmNode>>(std::move(chosen));
  if (targets.empty()) {
    err << "rcanctl: " << options.swarm_file << ": no nodes selected (the registry's 'nodes:' list is empty)\n";
    return false;
  }
  return true;
}

Operation operation_named(std::string_view verb) {
  return verb == "status" ? Operation::Status : verb == "stop" ? Operation::Stop : Operation::Command;
}

std::optional<int> parse_fleet_command(std::span<const std::string> args, Operation op, bool swarm, std::string_view usage,
                                       FleetOptions& options, std::ostream& out, std::ostream& err) {
  if (!parse_fleet_options(args, op, swarm, options, err)) {
    err << usage;
    return kExitUsage;
  }
  if (options.help) {
    out << usage;
    return kExitOk;
  }
  return std::nullopt;
}

int run_fleet_operation(Operation op, const std::vector<swarm::SwarmNode>& targets, const FleetOptions& options,
                        std::ostream& out, std::ostream& err) {
  std::vector<swarm::PeerRequest> requests;
  for (const auto& node : targets) {
    if (op == Operation::Status)
      requests.push_back(swarm::peer_request(node, "GET", "/api/status"));
    else if (op == Operation::Stop) {
      requests.push_back(swarm::peer_request(node, "POST", "/api/stop", json{{"reason", "rcanctl stop"}}.dump()));
      requests.back().body_limit = swarm::kStopAnswerLimit;
    } else
      requests.push_back(swarm::peer_request(node, "POST", "/api/command", json{{"instruction", options.instruction}}.dump()));
  }
  const int default_ms = op == Operation::Stop ? 400 : op == Operation::Status ? 2000 : 15000;
  // "*.local" hosts through avahi-daemon (no libnss-mdns needed); the Avahi client only when a target needs it.
  const bool any_local =
      std::any_of(targets.begin(), targets.end(), [](const auto& node) { return mdns::is_mdns_host(node.host); });
  swarm::FanOut fan_out(any_local ? local_name_resolver() : nullptr);
  auto results = fan_out.run_and_wait(std::move(requests), std::chrono::milliseconds(options.timeout_ms ? options.timeout_ms : default_ms));
  fan_out.stop();

  std::vector<Row> rows;
  std::size_t failed = 0;
  for (const auto& result : results) {
    rows.push_back(op == Operation::Status ? status_row(result) : action_row(op, result));
    failed += rows.back().ok ? 0 : 1;
  }
  if (options.json) {
    for (const auto& row : rows) out << row.object.dump(-1, ' ', false, json::error_handler_t::replace) << "\n";
  } else {
    print_table(op, rows, out);
  }
  if (failed > 0 && !options.json)
    err << "rcanctl: " << failed << " of " << rows.size() << " node(s) failed\n";
  return failed == 0 ? kExitOk : kExitPartial;
}

}  // namespace rcand::rcanctl
