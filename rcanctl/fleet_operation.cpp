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

#include "human_format.hpp"
#include "instance_problems.hpp"
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
  json object{{"name", result.name}, {"address", result.address}, {"reachable", result.reachable},
              {"ok", false},         {"http_status", nullptr},    {"state", nullptr},
              {"estopped", nullptr}, {"caps", json::array()},     {"latency_ms", std::round(result.latency_ms * 1000.0) / 1000.0},
              {"error", nullptr}};
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
  // Each instance that is not ok, with its reason and the fix the robot suggests (a degraded one too).
  const auto problems = status_problems(body);
  if (!problems.empty()) {
    object["problems"] = json::array();
    for (const auto& problem : problems) object["problems"].push_back(problem.to_json());
  }
  // A robot that answers but reports a fault (a failed plugin or driver) is not "ok": scripts see exit 1.
  if (object["state"] == "error") {
    std::string error = "the robot reports state error";
    if (!problems.empty())
      error += ": " + problems.front().summary() + (problems.front().hint.empty() ? "" : "; fix: " + problems.front().hint);
    object["error"] = error + " (rcanctl plugins lists every instance)";
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
  if (op == Operation::Status) {
    if (row.value("state", json()) == "error") return "state error (below)";
    return row.value("ok", false) ? "ok" : text_of(row, "error");
  }
  if (!row.value("ok", false)) {
    const std::string code = text_of(row, "code", "");
    return "FAILED: " + (code.empty() ? "" : code + ": ") + text_of(row, "error");
  }
  if (!row.value("executed", true)) return "acknowledged, not executed (" + text_of(row, "reason", "no reason") + ")";
  if (op == Operation::Stop) return "motors stopped";
  const json answer = row.value("response", json::object());
  if (!answer.is_object()) return "executed";
  if (answer.contains("hitl") && answer["hitl"].is_object()) return "waiting for a person's approval";
  if (!answer.contains("action") || answer["action"].is_null()) return "understood, nothing to do";
  return answer.value("dispatched", true) ? "done" : "not dispatched";
}

// What the robot made of an instruction, under the table: its words and the action it ran (the chat capability's
// answer, docs/protocol.md §7.5).
void print_understood(const json& row, std::ostream& out) {
  const json answer = row.value("response", json::object());
  if (!answer.is_object() || !row.value("ok", false)) return;
  const std::string name = text_of(row, "name");
  if (answer.contains("raw_text")) out << name << ": understood: " << text_of(answer, "raw_text") << "\n";
  // `action` is the action object ({"type": ...}), `request` the request the robot dispatched for it.
  const json action = answer.value("action", json());
  if (action.is_object()) {
    std::string fields;
    for (const auto& [key, value] : action.items())
      if (key != "type") fields += (fields.empty() ? "" : ", ") + key + " " + human_text(value);
    out << "  action: " << text_of(action, "type", "?") << (fields.empty() ? "" : " (" + fields + ")") << "\n";
  }
  const json request = answer.value("request", json());
  if (request.is_object()) out << "  request: " << text_of(request, "method", "") << " " << text_of(request, "path", "") << "\n";
  if (answer.contains("result") && answer["result"].is_object())
    out << "  result: " << answer["result"].dump(-1, ' ', false, json::error_handler_t::replace) << "\n";
  if (answer.contains("thought_id")) out << "  thought: " << text_of(answer, "thought_id") << "\n";
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
      for (const auto& cap : o["caps"])
        caps += (caps.empty() ? "" : ",") + (cap.is_string() ? cap.get<std::string>() : cap.dump());
    }
    std::ostringstream latency;
    latency << std::fixed << std::setprecision(1) << o.value("latency_ms", 0.0) << " ms";
    cells.push_back({text_of(o, "name"), o.value("address", std::string()).empty() ? "-" : text_of(o, "address"),
                     o.value("reachable", false) ? "yes" : "no", state, estop, caps, latency.str(), result_text(op, o)});
  }
  print_text_table(cells, out);
  if (op == Operation::Command)
    for (const auto& row : rows) print_understood(row.object, out);
  for (const auto& row : rows)  // what is wrong and how to fix it, under the table: too long for a cell
    if (row.object.contains("problems"))
      for (const auto& problem : row.object["problems"]) {
        const char* kind = problem.contains("driver") ? "driver" : "capability";
        out << text_of(row.object, "name") << ": " << kind << " " << text_of(problem, kind) << " " << text_of(problem, "state")
            << ": " << text_of(problem, "reason") << "\n";
        if (problem.contains("hint")) out << "  fix: " << text_of(problem, "hint") << "\n";
      }
}

}  // namespace

void add_fleet_options(CLI::App& app, Operation op, bool swarm_mode, FleetOptions& options) {
  if (op == Operation::Command)
    app.add_option("--instruction", options.instruction, "what the robot is to do, in words")->required();
  if (swarm_mode) {
    app.add_option("--node", options.nodes, "a node of the swarm file (repeat for more; default every node)")
        ->type_size(1)
        ->allow_extra_args(false);
    app.add_option("--tag", options.tags, "nodes carrying this tag (repeat: every tag)")->type_size(1)->allow_extra_args(false);
  } else {
    app.add_option("--node", options.nodes, "a node of the swarm file instead of --host/--port/--token")
        ->type_size(1)
        ->allow_extra_args(false);
  }
  app.add_option("--swarm", options.swarm_file, "the swarm file (default " + options.swarm_file + ")");
  app.add_flag("--json", options.json, "one JSON object per node per line");
  app.add_option("--timeout", options.timeout_ms, "milliseconds to wait (default: stop 400, status 2000, command 15000)")
      ->check(CLI::Range(1, 600000));
  if (swarm_mode) return;
  app.add_option("--host", options.host,
                 "the robot: HOST, HOST:PORT or https://HOST[:PORT] (default 127.0.0.1; TLS with https://)");
  app.add_option("--port", options.port, "its port (default 8000)")->check(CLI::Range(1, 65535));
  app.add_option("--token", options.token, "the bearer token (or --token-file, or $RCAND_TOKEN)");
  app.add_option("--token-file", options.token_file, "a file holding the token");
  add_tls_options(app, options.tls);
}

std::string finish_fleet_options(const CLI::App& app, bool swarm_mode, FleetOptions& options) {
  if (swarm_mode) return {};
  if (options.nodes.size() > 1) return "one --node at most (use rcanctl swarm for several)";
  bool addressed = false;
  for (const char* name : {"--host", "--port", "--token", "--token-file", "--cacert", "--cert", "--key"})
    addressed = addressed || app.count(name) > 0;
  if (!options.nodes.empty() && addressed)
    return "--node takes address, token and TLS from the swarm file; drop --host/--port/--token/--cacert";
  if (auto problem = finish_tls_options(options.tls, options.host, options.port); !problem.empty()) return problem;
  if (!options.token_file.empty()) {
    options.token = read_token_file(options.token_file);
    if (options.token.empty()) return "cannot read a token from --token-file " + options.token_file;
  }
  if (options.token.empty() && options.nodes.empty())
    if (const char* env = std::getenv("RCAND_TOKEN")) options.token = env;
  if (options.token.empty() && options.nodes.empty())
    return "a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN";
  return {};
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

int run_fleet_operation(Operation op, const std::vector<swarm::SwarmNode>& targets, const FleetOptions& options,
                        std::ostream& out, std::ostream& err) {
  std::vector<swarm::PeerRequest> requests;
  for (const auto& node : targets) {
    if (op == Operation::Status) requests.push_back(swarm::peer_request(node, "GET", "/api/status"));
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
  auto results =
      fan_out.run_and_wait(std::move(requests), std::chrono::milliseconds(options.timeout_ms ? options.timeout_ms : default_ms));
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
  if (failed > 0 && !options.json) err << "rcanctl: " << failed << " of " << rows.size() << " node(s) failed\n";
  return failed == 0 ? kExitOk : kExitPartial;
}

}  // namespace rcand::rcanctl
