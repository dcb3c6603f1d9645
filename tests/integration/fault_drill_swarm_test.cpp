// Fault drill: a swarm peer that accepts the forwarded stop and drops the connection mid-request. The broadcast stop
// still completes within 500 ms, the healthy peer stops, the dropping peer is reported failed, and neither robot
// loses an audit entry.
#include <doctest/doctest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <stdexcept>
#include <thread>

#include "fault_drill.hpp"
#include "libs/http/server.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

// Accepts every connection, reads the first bytes of the request, then closes it: a robot that dies mid-request.
class DroppingPeer {
 public:
  DroppingPeer() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof address;
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&address), size) != 0 || ::listen(fd_, 16) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size) != 0)
      throw std::runtime_error("DroppingPeer: cannot listen");
    port_ = ntohs(address.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~DroppingPeer() {
    stopping_ = true;
    thread_.join();
    ::close(fd_);
  }
  std::uint16_t port() const { return port_; }
  int dropped() const { return dropped_.load(); }

 private:
  void serve() {
    while (!stopping_) {
      pollfd ready{fd_, POLLIN, 0};
      if (::poll(&ready, 1, 50) <= 0) continue;
      const int client = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (client < 0) continue;
      pollfd data{client, POLLIN, 0};
      char buffer[32];
      if (::poll(&data, 1, 1000) > 0 && ::recv(client, buffer, sizeof buffer, 0) > 0) ++dropped_;  // part of the request
      ::close(client);
    }
  }

  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stopping_{false};
  std::atomic<int> dropped_{0};
  std::thread thread_;
};

}  // namespace

TEST_CASE("fault drill: a peer that drops the connection mid-request during a broadcast stop is reported, the rest stop") {
  TempDir dir;
  DroppingPeer dropper;
  RcandProcess bravo(swarm_robot_config("bravo"));
  const auto swarm_file =
      dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}, {"dropper", "127.0.0.1", dropper.port()}}));
  RcandProcess alpha(swarm_robot_config("alpha", swarm_file));

  for (int round = 0; round < 3; ++round) {
    const std::string id = "drop-broadcast-" + std::to_string(round);
    const auto start = std::chrono::steady_clock::now();
    const auto response = alpha.request("POST", "/api/stop", "guest-token", "", {{"X-Swarm-Broadcast", "true"}, {"X-Message-Id", id}});
    const auto took = std::chrono::steady_clock::now() - start;
    CHECK(response.status == 200);
    CHECK(took < drill::kStopLimit);
    const auto report = json::parse(response.body, nullptr, false);
    CHECK(report.value("estopped", false));
    CHECK(node_named(report, "alpha").value("ok", false));
    CHECK(node_named(report, "bravo").value("ok", false));
    const auto dropped = node_named(report, "dropper");
    CHECK_FALSE(dropped.value("ok", true));
    CHECK_FALSE(dropped.value("error", json()).is_null());
    drill::check_audit_complete(alpha, {id});
    drill::check_audit_complete(bravo, {id});  // the forwarded stop carries the broadcast's message id
  }
  CHECK(dropper.dropped() >= 3);  // it really received (part of) each forwarded request
  CHECK(bravo.json("GET", "/api/estop", "guest-token").value("estopped", false));
}

TEST_CASE("fault drill: a lying peer (\"motors_stopped\":\"yes\", \"ack\":\"yes\") is that node's failure; the robot stays up and latched") {
  // Issue 13 #1: a GUEST's broadcast stop aborted the broadcasting rcand when a peer answered with the wrong types.
  rcand::http::ServerOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  rcand::http::Server liar(options, [](rcand::http::Request&& request, rcand::http::Respond respond) {
    rcand::http::Response answer;
    answer.body = request.path == "/api/stop" ? R"({"status":"stopped","estopped":"yes","motors_stopped":"yes"})"
                                              : R"({"ack":"yes","executed":"no","reason":["estop_active"]})";
    respond(std::move(answer));
  });
  const auto liar_port = liar.start();
  TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"liar", "127.0.0.1", liar_port}}));
  RcandProcess alpha(swarm_robot_config("alpha", swarm_file));

  int status = 0;
  auto report = alpha.json("POST", "/api/stop", "guest-token", R"({"broadcast":true})", &status);
  CHECK(status == 200);
  CHECK(report["estopped"] == true);
  CHECK(node_named(report, "alpha")["ok"] == true);
  auto lied = node_named(report, "liar");
  CHECK(lied["ok"] == false);
  CHECK(lied["code"] == "MALFORMED_ANSWER");
  CHECK(report["summary"]["failed"] == 1);

  alpha.json("POST", "/api/estop/clear", "owner-token", "", &status);
  CHECK(status == 200);
  report = alpha.json("POST", "/api/command", "user-token", R"({"broadcast":true,"instruction":"wave"})", &status);
  CHECK(status == 200);
  CHECK(node_named(report, "liar")["ok"] == false);
  CHECK(node_named(report, "liar")["code"] == "MALFORMED_ANSWER");

  // Still the same process, still answering; a new stop still latches.
  CHECK(alpha.json("GET", "/health")["status"] == "ok");
  CHECK(alpha.json("POST", "/api/stop", "guest-token", "", &status)["estopped"] == true);
  CHECK(alpha.stop() == 0);
}
