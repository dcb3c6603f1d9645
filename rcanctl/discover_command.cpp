#include "discover_command.hpp"

#include <algorithm>
#include <iostream>
#include <sstream>

#include "fleet_operation.hpp"
#include "libs/mdns/service_browser.hpp"
#include "libs/swarm/fan_out.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

using nlohmann::json;

constexpr std::chrono::milliseconds kFetchTimeout{2000};

std::string joined(const json& list) {
  std::string out;
  if (!list.is_array()) return out;
  for (const auto& item : list) out += (out.empty() ? "" : ",") + (item.is_string() ? item.get<std::string>() : item.dump());
  return out;
}

std::vector<std::string> split_caps(const std::string& caps) {
  std::vector<std::string> out;
  std::stringstream in(caps);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

void print_table(const std::vector<json>& rows, std::ostream& out) {
  std::vector<std::vector<std::string>> cells{{"NAME", "RURI", "ADDRESS", "PORT", "CAPS", "STATUS", "CHECK"}};
  for (const auto& row : rows) {
    std::string check = "ok";
    if (!row["error"].is_null()) check = "UNREACHABLE: " + row["error"].get<std::string>();
    else if (!row["consistent"].get<bool>()) check = "DISAGREES: " + joined(row["mismatches"]);
    cells.push_back({row["name"], row["ruri"], row["address"], std::to_string(row["port"].get<int>()), joined(row["caps"]),
                     row["status"], check});
  }
  print_text_table(cells, out);
}

}  // namespace

std::vector<std::string> discovery_disagreements(const std::map<std::string, std::string>& txt, std::uint16_t port,
                                                 const json& discover) {
  std::vector<std::string> problems;
  if (!discover.is_object()) return {"the DISCOVER document is not a JSON object"};
  const json record = discover.value("txt_record", json::object());
  for (const auto& [key, value] : txt) {
    if (!record.contains(key)) problems.push_back("TXT " + key + " is missing from txt_record");
    else if (record[key] != value) problems.push_back("TXT " + key + "=" + value + " but txt_record says " + record[key].dump());
  }
  if (record.is_object())
    for (const auto& [key, value] : record.items())
      if (!txt.count(key)) problems.push_back("txt_record " + key + " is missing from TXT");
  // The §9.5 list, and the fields DISCOVER carries beside txt_record.
  const auto caps = txt.find("caps");
  if (caps == txt.end()) problems.push_back("TXT has no caps");
  else if (split_caps(caps->second) != discover.value("capabilities", std::vector<std::string>{}))
    problems.push_back("TXT caps=" + caps->second + " but capabilities[] is [" +
                       joined(discover.value("capabilities", json::array())) + "]");
  for (const char* key : {"ruri", "name", "status", "model", "version"}) {
    const auto found = txt.find(key);
    if (found != txt.end() && discover.contains(key) && discover[key] != found->second)
      problems.push_back(std::string("TXT ") + key + "=" + found->second + " but DISCOVER " + key + " is " +
                         discover[key].dump());
  }
  if (discover.value("port", 0) != port)
    problems.push_back("mDNS port " + std::to_string(port) + " but DISCOVER port is " + discover.value("port", json()).dump());
  return problems;
}

int run_discover(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  bool as_json = false;
  double timeout_s = 3.0;
  const auto app = make_command_app(
      "rcanctl discover",
      "Browses _rcan._tcp on the LAN (through avahi-daemon), resolves every robot and checks its DISCOVER document\n"
      "(GET /api/discovery) against its mDNS TXT record.",
      "Output: a table, or one JSON object per robot per line with --json.\n"
      "Exit: 0 robots found and all consistent, 1 none found or a robot disagrees / does not answer,\n"
      "2 usage error or avahi-daemon unreachable.");
  app->add_option("--timeout", timeout_s, "seconds to browse (default 3)")->check(CLI::Range(0.001, 3600.0));
  app->add_flag("--json", as_json, "one JSON object per robot per line");
  if (auto done = parse_command_line(*app, args, out, err)) return *done;

  const auto browsed = mdns::browse_services("_rcan._tcp", std::chrono::milliseconds(static_cast<long>(timeout_s * 1000)));
  if (!browsed.error.empty()) {
    err << "rcanctl discover: " << browsed.error << " (is avahi-daemon running?)\n";
    return kExitUsage;
  }
  if (browsed.services.empty()) {
    err << "rcanctl discover: no robot (_rcan._tcp) found within " << timeout_s << " s\n";
    return kExitPartial;
  }

  // Every robot's DISCOVER document, fetched in parallel (no token: DISCOVER is public, docs/protocol.md §5).
  std::vector<swarm::PeerRequest> requests;
  for (const auto& service : browsed.services) {
    swarm::PeerRequest request;
    request.name = service.name;
    request.host = service.address;
    request.port = service.port;
    request.target = "/api/discovery";
    requests.push_back(std::move(request));
  }
  swarm::FanOut fan_out;
  const auto fetched = fan_out.run_and_wait(std::move(requests), kFetchTimeout);

  std::vector<json> rows;
  bool all_good = true;
  for (std::size_t i = 0; i < browsed.services.size(); ++i) {
    const auto& service = browsed.services[i];
    const auto& result = fetched[i];
    const auto txt_value = [&](const char* key) {
      const auto found = service.txt.find(key);
      return found == service.txt.end() ? std::string("-") : found->second;
    };
    json row{{"name", service.name},          {"ruri", txt_value("ruri")}, {"host", service.host},
             {"address", service.address},    {"port", service.port},      {"caps", split_caps(txt_value("caps"))},
             {"status", txt_value("status")}, {"txt", service.txt},        {"consistent", false},
             {"mismatches", json::array()},   {"error", nullptr}};
    if (!result.reachable) {
      row["error"] = result.error;
    } else if (result.status != 200) {
      row["error"] = "GET /api/discovery answered " + std::to_string(result.status);
    } else {
      const json discover = json::parse(result.body, nullptr, false);
      const auto problems = discovery_disagreements(service.txt, service.port, discover);
      row["discovery"] = discover;
      row["mismatches"] = problems;
      row["consistent"] = problems.empty();
    }
    all_good = all_good && row["consistent"].get<bool>();
    rows.push_back(std::move(row));
  }
  if (as_json) {
    for (const auto& row : rows) out << row.dump() << "\n";
  } else {
    print_table(rows, out);
  }
  return all_good ? kExitOk : kExitPartial;
}

int run_discover(std::span<const std::string> args) { return run_discover(args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
