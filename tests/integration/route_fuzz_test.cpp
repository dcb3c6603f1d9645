// Type-confused JSON against every capability route of every first-party plugin of the bundled robot
// (config/sim-rover.rcan.yaml), on a real rcand (issue 28 item 10). The class of bug: a handler that reads a field with
// get<T>() or value() without checking its type throws nlohmann::json::type_error on a client's number-for-a-string,
// and before issue 28 that exception took the whole capability out of service until a restart (`POST
// /api/hitl/authorize {"decision": 5}` did so to chat).
//
// Nothing here is written by hand per route: the routes are the route table's rows, as GET /api/status lists them
// (capabilities.<name>.routes); the fields of each body are found from the routes' own answers - a 400 names the
// field at fault (`field`), and lists the values it takes (`allowed`) - and every field name any answer mentions is
// also tried on every other route. Then every field, and the body itself, is replaced by null, booleans, numbers
// (huge ones too), strings (empty, a control character, 200 KB), arrays and objects (nested, large).
//
// Every answer must be a 2xx or a 4xx - with the {"error","code","status"} body, a bounded one (no client value
// quoted whole) - never a 500 (a 503 is a capability's own "not now"); after each route its capability must still be
// "ok" with no handler errors.
#include <doctest/doctest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "libs/http/client.hpp"
#include "libs/yaml/yaml_document.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxErrorBytes = 8192;  // an error body; a client's 200 KB value quoted back would exceed it

// The bundled robot, with the test's credentials, on port 0, plugins and state from the test's own places.
json bundled_robot() {
  const std::filesystem::path file = std::filesystem::path(RCAND_SOURCE_DIR) / "config" / "sim-rover.rcan.yaml";
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  std::vector<rcand::yaml::ConfigDiagnostic> diagnostics;
  auto loaded = rcand::yaml::yaml_to_json(text.str(), file.string(), diagnostics);
  REQUIRE(loaded.ok);
  json config = loaded.doc;
  const json test = sim_config();
  config["runtime"]["auth"] = test["runtime"]["auth"];
  config["runtime"]["listen"] = test["runtime"]["listen"];
  config["runtime"]["rate_limit"] = test["runtime"]["rate_limit"];
  config["runtime"]["logging"] = {{"level", "warn"}};
  config["runtime"].erase("plugin_paths");
  config["runtime"].erase("state_dir");
  if (!std::filesystem::exists(plugin_dir() / "rcand_vision.so")) {  // built without OpenCV (RCAND_WITH_VISION=OFF)
    auto& caps = config["rcan_protocol"]["capabilities"];
    caps.erase(std::remove(caps.begin(), caps.end(), json("vision")), caps.end());
    config.erase("camera");
  }
  return config;
}

// Values of every JSON type, the huge and the hostile ones included.
std::vector<json> confused_values() {
  json nested = json::array();
  for (int i = 0; i < 50; ++i) nested = json::array({nested});
  json many = json::array();
  for (int i = 0; i < 5000; ++i) many.push_back(i);
  return {nullptr,
          true,
          false,
          0,
          -1,
          1,
          0.5,
          -0.5,
          1e308,
          -1e308,
          9223372036854775807LL,
          18446744073709551615ULL,
          "",
          "x",
          "open",
          "th-0123456789abcdef",
          std::string("a\x01\x7f\xe2\x80\xae"),
          std::string(200 * 1024, 'z'),
          json::array(),
          json::array({1, "a", nullptr}),
          json::object(),
          json{{"a", 1}, {"", {{"b", json::array()}}}},
          nested,
          many};
}
// One of each type, for field names tried on routes that did not name them.
std::vector<json> type_values() { return {nullptr, 7, "x", json::array({1}), json{{"a", 1}}, std::string(20 * 1024, 'y')}; }

struct Route {
  std::string capability, method, path, type;  // type: the body "type" of a POST /api/action row
  bool stream = false, motion = false;
};

struct Answer {
  int status = 0;
  json body;
  std::size_t bytes = 0;
};

// A GET stream route may never end (MJPEG): send the request and read only its status line.
int stream_status(std::uint16_t port, const std::string& method, const std::string& target, const std::string& body) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  REQUIRE(fd >= 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
  const std::string request = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer owner-token\r\n" +
                              "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                              "\r\nConnection: close\r\n\r\n" + body;
  for (std::size_t sent = 0; sent < request.size();) {
    const auto n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<std::size_t>(n);
  }
  std::string head;
  char buffer[4096];
  while (head.find("\r\n") == std::string::npos) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10000) <= 0) break;
    const auto n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    head.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return head.rfind("HTTP/1.1 ", 0) == 0 ? std::stoi(head.substr(9, 3)) : 0;
}

class RouteFuzzer {
 public:
  explicit RouteFuzzer(const RcandProcess& rcand) : rcand_(rcand), client_("127.0.0.1", rcand.port(), std::chrono::seconds(10)) {}

  std::vector<Route> routes() {
    const json status = rcand_.json("GET", "/api/status", "owner-token");
    std::vector<Route> list;
    for (const auto& name_item_case : status.at("capabilities").items()) {
      const std::string& name = name_item_case.key();  // clang 14: a lambda cannot capture a structured binding
      const auto& item = name_item_case.value();
      CHECK_MESSAGE(item.value("state", "") == "ok", name << ": " << item.dump());
      for (const auto& row : item.value("routes", json::array()))
        list.push_back({name, row.at("method").get<std::string>(), row.at("path").get<std::string>(), row.value("type", ""),
                        row.value("stream", false), row.value("motion", false)});
    }
    return list;
  }

  // Everything for one route; the field names it learns are kept for the routes after it (and a second pass).
  void fuzz(const Route& route) {
    for (const auto& value : confused_values()) send(route, value);  // the body itself
    send_text(route, "{\"unterminated\": ");
    send_text(route, std::string(100, '[') + std::string(100, ']'));  // deeper than rcand's parser allows
    json seed = route.type.empty() ? json::object() : json{{"type", route.type}};
    discover(route, seed);
    for (const auto& [field, good] : seed.items()) {
      json without = seed;
      without.erase(field);
      send(route, without);
      for (const auto& value : confused_values()) send(route, with(seed, field, value));
    }
    for (const auto& field : std::set<std::string>(dictionary_)) {
      if (seed.contains(field)) continue;
      for (const auto& value : type_values()) send(route, with(seed, field, value));
    }
  }

  void check_still_ok(const std::string& capability) {
    const json item = rcand_.json("GET", "/api/status", "owner-token")["capabilities"][capability];
    CHECK_MESSAGE(item.value("state", "") == "ok", capability << " after its routes were fuzzed: " << item.dump());
    CHECK_MESSAGE(!item.contains("handler_errors"), capability << ": a handler threw: " << item.dump());
  }

  const std::vector<std::string>& failures() const { return failures_; }
  std::size_t requests() const { return requests_; }
  const std::set<std::string>& dictionary() const { return dictionary_; }

 private:
  static json with(json body, const std::string& field, const json& value) {
    body[field] = value;
    return body;
  }

  // Finds the fields the route asks for, one 400 at a time, and a value that gets past each.
  void discover(const Route& route, json& seed) {
    for (int round = 0; round < 8; ++round) {
      const Answer a = send(route, seed);
      const std::string field = top_field(a);
      if (field.empty() || seed.contains(field)) return;
      std::vector<json> candidates = allowed_of(a);
      for (const auto& v : confused_values()) candidates.push_back(v);
      bool passed = false;
      for (const auto& value : candidates) {
        const Answer b = send(route, with(seed, field, value));
        if (top_field(b) != field) {
          seed[field] = value;
          passed = true;
          break;
        }
      }
      if (!passed) {
        seed[field] = "x";  // nothing gets past it: its confusion pass still runs
        return;
      }
    }
  }

  // The top-level body field a 400 names ("joints.elbow" -> "joints"); "" for none or the body itself.
  static std::string top_field(const Answer& a) {
    if (a.status != 400 || !a.body.is_object() || !a.body.contains("field") || !a.body["field"].is_string()) return "";
    std::string field = a.body["field"];
    field = field.substr(0, field.find('.'));
    return field == "body" ? "" : field;
  }
  static std::vector<json> allowed_of(const Answer& a) {
    std::vector<json> values;
    if (a.body.is_object() && a.body.contains("allowed") && a.body["allowed"].is_array())
      for (const auto& v : a.body["allowed"]) values.push_back(v);
    return values;
  }

  Answer send(const Route& route, const json& body) { return send_text(route, body.dump()); }

  Answer send_text(const Route& route, const std::string& body) {
    const std::string target = concrete(route.path);
    ++requests_;
    if (route.stream && route.method == "GET") {
      const int status = stream_status(rcand_.port(), route.method, target, body);
      if (status < 200 || (status >= 500 && status != 503)) fail(route, body, "answered " + std::to_string(status));
      return {status, json(), 0};
    }
    Answer a = exchange(route.method, target, body);
    if (a.status == 423 && route.motion) {  // an earlier case latched the e-stop (an obstacle): clear it, ask again
      exchange("POST", "/api/estop/clear", "");
      a = exchange(route.method, target, body);
    }
    learn(a);
    // 503 is a capability's own "not now" (no depth reading yet, no actuator); one that went out of service is caught
    // by check_still_ok. Any other 5xx - the 500 of a handler that threw above all - is the bug this test looks for.
    if (a.status < 200 || (a.status >= 500 && a.status != 503))
      fail(route, body, "answered " + std::to_string(a.status) + " " + a.body.dump().substr(0, 300));
    if (a.status >= 400) {
      const bool shaped =
          a.body.is_object() && a.body.contains("error") && a.body.contains("code") && a.body.value("status", 0) == a.status;
      if (!shaped) fail(route, body, "an error without the {error, code, status} body: " + a.body.dump().substr(0, 300));
      if (a.bytes > kMaxErrorBytes)
        fail(route, body, "an error body of " + std::to_string(a.bytes) + " bytes: " + a.body.dump().substr(0, 300));
    }
    return a;
  }

  Answer exchange(const std::string& method, const std::string& target, const std::string& body) {
    const auto response = client_.request(method, target, body, {{"Authorization", "Bearer owner-token"}});
    return {response.status, json::parse(response.body, nullptr, false), response.body.size()};
  }

  // Field names for the other routes: whatever a 400 names, and the quoted names in its message.
  void learn(const Answer& a) {
    if (a.status != 400 || !a.body.is_object()) return;
    if (const std::string f = top_field(a); !f.empty()) dictionary_.insert(f);
    static const std::regex quoted("\"([a-z][a-z0-9_]{1,31})\"");
    const std::string message = a.body.value("error", "");
    for (std::sregex_iterator it(message.begin(), message.end(), quoted), end; it != end; ++it) dictionary_.insert((*it)[1]);
  }

  static std::string concrete(const std::string& path) {
    return path.ends_with('*') ? path.substr(0, path.size() - 1) + "th-0123456789abcdef" : path;
  }

  void fail(const Route& route, const std::string& body, const std::string& what) {
    if (failures_.size() < 40)
      failures_.push_back(route.method + " " + route.path + (route.type.empty() ? "" : " (" + route.type + ")") + " with " +
                          body.substr(0, 160) + (body.size() > 160 ? "... (" + std::to_string(body.size()) + " bytes)" : "") +
                          ": " + what);
  }

  const RcandProcess& rcand_;
  rcand::http::Client client_;
  std::set<std::string> dictionary_;
  std::vector<std::string> failures_;
  std::size_t requests_ = 0;
};

}  // namespace

TEST_CASE("every capability route of the bundled robot answers type-confused JSON with a 4xx, and stays in service") {
  RcandProcess rcand(bundled_robot());
  RouteFuzzer fuzzer(rcand);
  const auto routes = fuzzer.routes();
  std::set<std::string> capabilities;
  for (const auto& r : routes) capabilities.insert(r.capability);
  // The bundled robot's capabilities with plugins of their own, all of them serving routes.
  for (const char* name : {"arm", "chat", "com.acme.gripper", "nav", "teleop"}) CHECK_MESSAGE(capabilities.contains(name), name);
  if (std::filesystem::exists(plugin_dir() / "rcand_vision.so")) CHECK(capabilities.contains("vision"));
  // The route is among them, found in the table, not written here.
  CHECK(std::any_of(routes.begin(), routes.end(), [](const Route& r) { return r.path == "/api/hitl/authorize"; }));

  for (int pass = 0; pass < 2; ++pass)  // the second pass tries the field names the later routes taught
    for (const auto& route : routes) {
      CAPTURE(route.method + " " + route.path);
      fuzzer.fuzz(route);
      fuzzer.check_still_ok(route.capability);
    }
  MESSAGE(fuzzer.requests() << " requests to " << routes.size() << " routes of " << capabilities.size()
                            << " capabilities; field names learned: " << json(fuzzer.dictionary()).dump());
  std::string report;
  for (const auto& f : fuzzer.failures()) report += "\n  " + f;
  CHECK_MESSAGE(fuzzer.failures().empty(), "answers that were not a bounded 2xx/4xx:" << report);
  for (const auto& name : capabilities) fuzzer.check_still_ok(name);
  CHECK(rcand.stop() == 0);
}
