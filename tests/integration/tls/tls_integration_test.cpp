// runtime.listen.tls (issue 19) against real rcand processes and a throwaway PKI (tests/support/tls_lab.hpp): HTTPS
// and wss with a good certificate, refusals for a certificate of another CA and an expired one, mutual TLS, plain
// HTTP refused on the TLS port but served on the loopback plain port, named start-up errors for bad files, and the
// swarm fan-out verifying each node against its own `ca`, and R2R dialing a TLS-only robot over wss.
#include <doctest/doctest.h>
#include <signal.h>
#include <sys/stat.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>

#include <chrono>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>

#include "fault_drill.hpp"
#include "libs/http/client.hpp"
#include "libs/http/tls_context.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "temp_dir.hpp"
#include "tls_lab.hpp"

using namespace rcand::test;
using nlohmann::json;
namespace http = rcand::http;
using namespace std::chrono_literals;

namespace {

json tls_robot_config(const TlsLab& lab, const std::string& cert, const std::string& client_ca = {}) {
  json config = sim_config();
  config["runtime"]["listen"]["tls"] = lab.listen_tls(cert, client_ca);
  return config;
}

http::ClientTlsSettings trusting(const TlsLab& lab, const std::string& ca, const std::string& client = {}) {
  http::ClientTlsSettings tls;
  tls.ca_file = lab.pem(ca);
  if (!client.empty()) {
    tls.cert_file = lab.pem(client);
    tls.key_file = lab.key(client);
  }
  return tls;
}

// The message of the ClientError one request over TLS ends in ("" when it was answered).
std::string tls_refusal(std::uint16_t port, const http::ClientTlsSettings& tls, const std::string& method,
                        const std::string& target) {
  try {
    http::request("127.0.0.1", port, method, target, method == "POST" ? R"({"reason":"tls test"})" : "",
                  {{"Authorization", "Bearer owner-token"}}, 5s, tls);
  } catch (const http::ClientError& e) {
    return e.what();
  }
  return {};
}

bool estopped(const RcandProcess& robot) { return robot.json("GET", "/api/estop", "guest-token")["estopped"] == true; }

// One frame of WS /ws/telemetry over wss, or the reason there is none.
std::string first_wss_frame(std::uint16_t port, const TlsLab& lab) {
  namespace net = boost::asio;
  namespace beast = boost::beast;
  net::io_context ioc;
  auto context = http::make_client_tls_context(trusting(lab, "ca"));
  beast::websocket::stream<beast::ssl_stream<beast::tcp_stream>> ws(ioc, *context);
  beast::error_code ec;
  beast::get_lowest_layer(ws).expires_after(5s);
  beast::get_lowest_layer(ws).connect(net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), port), ec);
  if (ec) return "connect: " + ec.message();
  http::expect_server_name(ws.next_layer().native_handle(), "127.0.0.1");
  ws.next_layer().handshake(net::ssl::stream_base::client, ec);
  if (ec) return "TLS: " + ec.message();
  ws.set_option(beast::websocket::stream_base::decorator(
      [](beast::websocket::request_type& request) { request.set(beast::http::field::authorization, "Bearer guest-token"); }));
  ws.handshake("127.0.0.1:" + std::to_string(port), "/ws/telemetry", ec);
  if (ec) return "upgrade: " + ec.message();
  beast::flat_buffer buffer;
  ws.read(buffer, ec);
  if (ec) return "read: " + ec.message();
  return beast::buffers_to_string(buffer.data());
}

// rcand --check-config on `config` written next to the JWT secret it names.
ProcessResult check_config(const json& config) {
  TempDir dir;
  dir.write("jwt.secret", kJwtSecret);
  const auto file = dir.write("robot.rcan.yaml", config.dump(2));
  return run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
}

}  // namespace

TEST_CASE("tls: a good certificate serves https and wss; plain HTTP is refused there and served on loopback") {
  TlsLab lab;
  RcandProcess robot(tls_robot_config(lab, "server"));
  REQUIRE(robot.tls_port() != 0);
  REQUIRE(robot.tls_port() != robot.port());

  // The test client: status then stop on one kept-alive TLS connection.
  http::Client client("127.0.0.1", robot.tls_port(), 5s, trusting(lab, "ca"));
  const auto status = client.request("GET", "/api/status", {}, {{"Authorization", "Bearer guest-token"}});
  CHECK(status.status == 200);
  CHECK(json::parse(status.body, nullptr, false).contains("state"));
  const auto stop = client.request("POST", "/api/stop", R"({"reason":"tls test"})", {{"Authorization", "Bearer user-token"}});
  CHECK(stop.status == 200);
  CHECK(json::parse(stop.body, nullptr, false)["estopped"] == true);
  CHECK(estopped(robot));

  // rcanctl: an https:// host with --cacert, and --cacert with --host/--port.
  const std::string url = "https://127.0.0.1:" + std::to_string(robot.tls_port());
  const auto ctl_status = run_tool(
      rcanctl_binary(), {"status", "--host", url, "--cacert", lab.pem("ca").string(), "--token", "owner-token", "--json"});
  const std::string status_output = ctl_status.out + ctl_status.err;
  CHECK_MESSAGE(ctl_status.exit_code == 0, status_output);
  CHECK(ctl_status.out.find("\"reachable\":true") != std::string::npos);
  const auto ctl_estop = run_tool(rcanctl_binary(), {"estop", "--host", "127.0.0.1", "--port", std::to_string(robot.tls_port()),
                                                     "--cacert", lab.pem("ca").string(), "--token", "owner-token", "--json"});
  CHECK_MESSAGE(ctl_estop.exit_code == 0, ctl_estop.err);
  CHECK(json::parse(ctl_estop.out, nullptr, false)["estopped"] == true);

  // wss: the telemetry WebSocket over the same TLS port.
  const auto frame = json::parse(first_wss_frame(robot.tls_port(), lab), nullptr, false);
  CHECK(frame.is_object());
  CHECK(frame.value("type", "") == "telemetry");
  const auto watched = run_tool(rcanctl_binary(), {"watch", "--host", url, "--cacert", lab.pem("ca").string(), "--token",
                                                   "guest-token", "--frames", "1", "--json"});
  CHECK_MESSAGE(watched.exit_code == 0, watched.err);
  CHECK(json::parse(watched.out, nullptr, false).value("type", "") == "telemetry");

  // Plain HTTP on the TLS port: one plain answer saying so, and nothing served.
  const auto plain_on_tls = http::request("127.0.0.1", robot.tls_port(), "GET", "/api/status", {}, {}, 5s);
  CHECK(plain_on_tls.status == 400);
  CHECK(json::parse(plain_on_tls.body, nullptr, false)["code"] == "TLS_REQUIRED");
  // The loopback plain port keeps local tools (and the stop lane) working.
  const auto local = robot.request("GET", "/api/status", "guest-token");
  CHECK_MESSAGE(local.status == 200, local.body);
  const auto ctl_plain = run_tool(rcanctl_binary(), {"status", "--port", std::to_string(robot.port()), "--token", "owner-token"});
  CHECK_MESSAGE(ctl_plain.exit_code == 0, ctl_plain.err);
}

TEST_CASE("tls: a certificate from another CA is refused with a clear message, and nothing is sent") {
  TlsLab lab;
  RcandProcess robot(tls_robot_config(lab, "other"));
  const auto why = tls_refusal(robot.tls_port(), trusting(lab, "ca"), "POST", "/api/stop");
  CHECK(why.find("TLS handshake with 127.0.0.1:") != std::string::npos);
  CHECK(why.find("certificate verify failed") != std::string::npos);
  CHECK(why.find("not signed by the CA this client trusts") != std::string::npos);
  CHECK_FALSE(estopped(robot));  // the stop never left the client
  const auto ctl = run_tool(rcanctl_binary(), {"stop", "--host", "https://127.0.0.1:" + std::to_string(robot.tls_port()),
                                               "--cacert", lab.pem("ca").string(), "--token", "owner-token", "--json"});
  CHECK(ctl.exit_code == 1);
  CHECK((ctl.out + ctl.err).find("certificate verify failed") != std::string::npos);
  CHECK_FALSE(estopped(robot));
  // The right CA is all it takes.
  CHECK(tls_refusal(robot.tls_port(), trusting(lab, "other-ca"), "GET", "/api/status").empty());
}

TEST_CASE("tls: an expired certificate is refused by clients; rcand starts and warns") {
  TlsLab lab;
  RcandProcess robot(tls_robot_config(lab, "expired"));
  const auto why = tls_refusal(robot.tls_port(), trusting(lab, "ca"), "POST", "/api/stop");
  CHECK(why.find("certificate verify failed: certificate has expired") != std::string::npos);
  CHECK_FALSE(estopped(robot));
  CHECK(robot.stderr_text().find("the certificate has expired") != std::string::npos);
}

TEST_CASE("tls: mutual TLS refuses a client without a certificate and serves one the CA signed") {
  TlsLab lab;
  RcandProcess robot(tls_robot_config(lab, "server", "ca"));
  const auto without = tls_refusal(robot.tls_port(), trusting(lab, "ca"), "POST", "/api/stop");
  CHECK(without.find("TLS") != std::string::npos);
  CHECK(without.find("client certificate") != std::string::npos);
  CHECK_FALSE(estopped(robot));
  // A certificate of another CA is no better.
  CHECK_FALSE(tls_refusal(robot.tls_port(), trusting(lab, "ca", "other"), "GET", "/api/status").empty());
  CHECK(tls_refusal(robot.tls_port(), trusting(lab, "ca", "client"), "POST", "/api/stop").empty());
  CHECK(estopped(robot));
  const auto ctl = run_tool(rcanctl_binary(), {"status", "--host", "https://127.0.0.1:" + std::to_string(robot.tls_port()),
                                               "--cacert", lab.pem("ca").string(), "--cert", lab.pem("client").string(), "--key",
                                               lab.key("client").string(), "--token", "owner-token"});
  const std::string output = ctl.out + ctl.err;
  CHECK_MESSAGE(ctl.exit_code == 0, output);
}

TEST_CASE("tls: a missing, mismatched or world-readable key is named by --check-config, and rcand does not start") {
  TlsLab lab;
  json mismatched = tls_robot_config(lab, "server");
  mismatched["runtime"]["listen"]["tls"]["key_file"] = lab.key("other").string();
  auto result = check_config(mismatched);
  CHECK(result.exit_code == 1);
  INFO(result.err);
  CHECK(result.err.find("runtime.listen.tls.key_file '" + lab.key("other").string() + "' does not match the certificate") !=
        std::string::npos);

  json missing = tls_robot_config(lab, "server");
  missing["runtime"]["listen"]["tls"]["cert_file"] = (lab.dir() / "nowhere.pem").string();
  result = check_config(missing);
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("runtime.listen.tls.cert_file '" + (lab.dir() / "nowhere.pem").string() +
                        "': cannot read: No such file or directory") != std::string::npos);

  ::chmod(lab.key("server").c_str(), 0644);
  result = check_config(tls_robot_config(lab, "server"));
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("other users may read or write this private key (mode 0644)") != std::string::npos);
  std::string refused;
  try {
    RcandProcess robot(tls_robot_config(lab, "server"));
  } catch (const std::runtime_error& e) {
    refused = e.what();
  }
  CHECK(refused.find("other users may read or write this private key") != std::string::npos);
  ::chmod(lab.key("server").c_str(), 0600);

  json incomplete = sim_config();
  incomplete["runtime"]["listen"]["tls"] = {{"cert_file", lab.pem("server").string()}};
  result = check_config(incomplete);
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("key_file") != std::string::npos);
  CHECK(check_config(tls_robot_config(lab, "server", "ca")).exit_code == 0);
}

TEST_CASE("tls: the swarm fan-out verifies each node against its own ca (and presents a client certificate)") {
  TlsLab lab;
  RcandProcess bravo(tls_robot_config(lab, "server", "ca"));
  RcandProcess charlie(tls_robot_config(lab, "other"));
  auto node = [](const std::string& name, std::uint16_t port, const std::filesystem::path& ca) {
    return json{{"name", name}, {"host", "127.0.0.1"}, {"port", port}, {"token", "owner-token"}, {"ca", ca.string()}};
  };
  json bravo_node = node("bravo", bravo.tls_port(), lab.pem("ca"));
  bravo_node["cert"] = lab.pem("client").string();
  bravo_node["key"] = lab.key("client").string();
  const json swarm{{"nodes", json::array({bravo_node, node("charlie", charlie.tls_port(), lab.pem("other-ca")),
                                          node("charlie-wrong-ca", charlie.tls_port(), lab.pem("ca")),
                                          node("bravo-no-client-cert", bravo.tls_port(), lab.pem("ca"))})}};
  TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", swarm.dump(2));
  const auto result = run_tool(rcanctl_binary(), {"swarm", "status", "--swarm", swarm_file.string(), "--json"});
  CHECK(result.exit_code == 1);  // two of four fail
  std::map<std::string, json> by_name;
  std::istringstream lines(result.out);
  for (std::string line; std::getline(lines, line);) {
    const json row = json::parse(line, nullptr, false);
    if (row.is_object()) by_name[row.value("name", "")] = row;
  }
  CHECK(by_name["bravo"]["reachable"] == true);
  CHECK(by_name["charlie"]["reachable"] == true);
  CHECK(by_name["charlie-wrong-ca"]["reachable"] == false);
  CHECK(by_name["charlie-wrong-ca"].dump().find("certificate verify failed") != std::string::npos);
  CHECK(by_name["bravo-no-client-cert"]["reachable"] == false);

  // A ca that cannot be read is a swarm.yaml error, named with its node.
  const json broken{{"nodes", json::array({node("bravo", bravo.tls_port(), dir.path() / "missing-ca.pem")})}};
  const auto broken_file = dir.write("broken.yaml", broken.dump(2));
  const auto refused = run_tool(rcanctl_binary(), {"swarm", "status", "--swarm", broken_file.string()});
  CHECK(refused.exit_code == 2);
  CHECK(refused.err.find("node 'bravo' ca: cannot read '") != std::string::npos);
}

TEST_CASE("tls: SIGHUP reads renewed files for new connections; a bad pair keeps the files in use") {
  TlsLab lab;
  TempDir live;
  auto install = [&](const std::string& cert, const std::string& key) {
    std::filesystem::copy_file(lab.pem(cert), live.path() / "robot.pem", std::filesystem::copy_options::overwrite_existing);
    std::filesystem::copy_file(lab.key(key), live.path() / "robot.key", std::filesystem::copy_options::overwrite_existing);
    ::chmod((live.path() / "robot.key").c_str(), 0600);
  };
  install("server", "server");
  json config = sim_config();
  config["runtime"]["listen"]["tls"] = {{"cert_file", (live.path() / "robot.pem").string()},
                                        {"key_file", (live.path() / "robot.key").string()}};
  RcandProcess robot(config);
  http::Client before("127.0.0.1", robot.tls_port(), 5s, trusting(lab, "ca"));
  REQUIRE(before.request("GET", "/api/status", {}, {{"Authorization", "Bearer guest-token"}}).status == 200);
  auto reload = [&](std::size_t nth) {
    REQUIRE(::kill(robot.pid(), SIGHUP) == 0);
    REQUIRE(drill::eventually([&] { return count_of(robot.stderr_text(), "config reload from") >= nth; }));
  };

  install("other", "other");  // renewed in place: same paths, another CA
  reload(1);
  CHECK(tls_refusal(robot.tls_port(), trusting(lab, "other-ca"), "GET", "/api/status").empty());
  CHECK(tls_refusal(robot.tls_port(), trusting(lab, "ca"), "GET", "/api/status").find("certificate verify failed") !=
        std::string::npos);
  // An open connection keeps the certificate it began with.
  CHECK(before.request("GET", "/api/status", {}, {{"Authorization", "Bearer guest-token"}}).status == 200);

  install("server", "other");  // a key that does not match: the reload is refused, the files in use stay
  reload(2);
  CHECK(robot.stderr_text().find("does not match the certificate") != std::string::npos);
  CHECK(tls_refusal(robot.tls_port(), trusting(lab, "other-ca"), "GET", "/api/status").empty());
}

TEST_CASE("tls: R2R dials a TLS-only robot of swarm.yaml over wss, checked against the node's ca") {
  TlsLab lab;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  json bravo_config = r2r_robot_config("bravo", token);
  bravo_config["runtime"]["listen"]["tls"] = lab.listen_tls("server");
  RcandProcess bravo(bravo_config);
  // alpha's status broadcasts reach bravo only through the connection alpha dials: bravo serves wss alone.
  const json swarm{{"nodes", json::array({{{"name", "bravo"},
                                           {"host", "127.0.0.1"},
                                           {"port", bravo.tls_port()},
                                           {"token", "owner-token"},
                                           {"ca", lab.pem("ca").string()}}})}};
  RcandProcess alpha(r2r_robot_config("alpha", token, 0, 0, dir.write("swarm.yaml", swarm.dump(2))));
  const auto heard = poll_until<json>([&] { return peer_status(bravo, "alpha"); });
  REQUIRE(heard);
  CHECK((*heard)["transport"] == "ws");
}
