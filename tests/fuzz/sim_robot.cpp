#include "sim_robot.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>

#include "fuzz_check.hpp"
#include "kernel/api/api.hpp"
#include "kernel/kernel.hpp"
#include "kernel/service.hpp"
#include "libs/base/logging.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/rcan/crypto.hpp"

namespace rcand::fuzz {
namespace {

namespace fs = std::filesystem;

// Same robot as config/sim-rover.rcan.yaml (its drive, nav, arm and gripper; no camera or chat), plus R2R over
// WebSocket, a short handler timeout, and a swarm whose peers refuse at once (port 1 on loopback), so a broadcast
// exercises node selection and the fan-out without waiting.
std::string robot_yaml() {
  return R"(rcan_version: "1.3"
metadata: {robot_name: fuzz-rover, robot_uuid: 5f3c2a1b-8d4e-4f6a-9b7c-1d2e3f4a5b6c, manufacturer: rcand, model: sim-rover}
physics:
  type: differential
  wheel_circumference_m: 0.21
  turn_time_per_deg_s: 0.008
  max_wheel_rps: 1.0
  kinematics:
    - {joint: shoulder, min_deg: -90, max_deg: 90, max_velocity_dps: 60, max_step_deg: 90}
    - {joint: elbow, min_deg: 0, max_deg: 135, max_velocity_dps: 90, max_step_deg: 90, home_deg: 90}
    - {joint: gripper, min_deg: 0, max_deg: 60, max_velocity_dps: 120, max_step_deg: 60}
drivers:
  - {id: drive0, protocol: sim_diff_drive}
  - {id: gripper0, protocol: acme_gripper_sim}
  - {id: arm0, protocol: sim_arm}
rcan_protocol: {port: 8000, capabilities: [status, teleop, nav, arm, com.acme.gripper], enable_mdns: false, enable_jwt: true}
safety: {watchdog_ms: 500}
runtime:
  listen: {address: 127.0.0.1}
  plugin_paths: [")" RCAND_PLUGIN_DIR R"("]
  swarm_file: swarm.yaml
  handler_timeout_ms: 2000
  auth:
    mode: tokens
    jwt_secret_file: jwt.secret
    tokens:
      - {principal: fuzz-owner, role: owner, sha256: )" +
         rcand::sha256_hex(kOwnerToken) + R"(}
      - {principal: fuzz-guest, role: guest, sha256: )" +
         rcand::sha256_hex(kGuestToken) + R"(}
  capabilities:
    arm: {gripper_joint: gripper, poses: {rest: {shoulder: 0, elbow: 90}, ready: {shoulder: 0, elbow: 45}}}
  state_dir: state
  r2r: {enabled: true, udp_enabled: false, status_interval_ms: 1000}   # WS /ws/r2r on the served port only
  logging: {level: error}
  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}   # every input reaches the code it aims at
)";
}

constexpr const char* kSwarmYaml = R"(nodes:
  - {name: alpha, host: 127.0.0.1, port: 1, token: peer-token-a, tags: [rover, rpi5]}
  - {name: bravo, host: 127.0.0.1, port: 1, token: peer-token-b, tags: [arm]}
)";

void write_file(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << text;
}

// The scratch directory: the config files live only while the kernel reads them; the state directory (the e-stop
// latch record, written once the robot serves) until the process exits.
fs::path& scratch_dir() {
  static fs::path* dir = new fs::path;
  return *dir;
}

void remove_scratch_dir() {
  std::error_code ec;
  if (!scratch_dir().empty()) fs::remove_all(scratch_dir(), ec);
}

struct Robot {
  std::unique_ptr<kernel::Kernel> instance;

  Robot() {
    rcand::configure_logging("off");
    char pattern[] = "/tmp/rcand-fuzz-XXXXXX";
    const char* made = ::mkdtemp(pattern);
    RCAND_FUZZ_CHECK(made != nullptr, "cannot create a scratch directory");
    const fs::path dir = made;
    scratch_dir() = dir;
    std::atexit(remove_scratch_dir);
    write_file(dir / "jwt.secret", "fuzz-jwt-secret-0123456789abcdef\n");
    write_file(dir / "swarm.yaml", kSwarmYaml);
    write_file(dir / "robot.rcan.yaml", robot_yaml());
    auto loaded = config::load_robot_config(dir / "robot.rcan.yaml");
    kernel::KernelOptions options;
    options.services = kernel::linked_services();  // swarm broadcasts, R2R and telemetry, as in rcand
    options.port = 0;                              // only serve_robot() binds, to a free port
    instance = std::make_unique<kernel::Kernel>(std::move(loaded.config), std::move(options));
    for (const char* file : {"jwt.secret", "swarm.yaml", "robot.rcan.yaml"}) fs::remove(dir / file);
  }
};

Robot* the_fuzz_robot = nullptr;

// At exit, before the scratch directory goes and before spdlog's registry is destroyed (both were set up earlier, so
// their exit handlers run later): without it the kernel's latch writer, woken by the last input's stop or clear,
// failed to write into the removed state directory and logged through the destroyed registry - a SEGV after the
// run that libFuzzer blamed on the empty input (crash-da39a3ee...).
void shut_down_fuzz_robot() {
  if (the_fuzz_robot != nullptr) the_fuzz_robot->instance->shutdown();
}

Robot& robot() {
  // Built once and never destroyed: libFuzzer may exit from any thread, and the kernel's threads must not race
  // static destructors then (a global pointer keeps it reachable, so it is no leak either). Shut down at exit.
  static Robot* instance = [] {
    the_fuzz_robot = new Robot;
    std::atexit(shut_down_fuzz_robot);
    return the_fuzz_robot;
  }();
  return *instance;
}

kernel::Api& api() { return robot().instance->api(); }

void check_answer(const http::Response& response) {
  RCAND_FUZZ_CHECK(response.status >= 200 && response.status <= 599, "status outside 200..599");
  RCAND_FUZZ_CHECK(response.status != 500, "500 INTERNAL: bad input must get a clear error");
  if (response.status < 400) return;
  const auto body = nlohmann::json::parse(response.body, nullptr, false);
  RCAND_FUZZ_CHECK(body.is_object(), "an error body is a JSON object");
  RCAND_FUZZ_CHECK(body.contains("error") && body["error"].is_string(), "an error has a message");
  RCAND_FUZZ_CHECK(body.contains("code") && body["code"].is_string() && !body["code"].get<std::string>().empty(),
                   "an error has a code");
  RCAND_FUZZ_CHECK(body.value("status", 0) == response.status, "an error body repeats its status");
}

}  // namespace

http::Response call(http::Request request) {
  auto answer = std::make_shared<std::promise<http::Response>>();
  auto answered = std::make_shared<std::atomic<bool>>(false);
  auto future = answer->get_future();
  http::Response response;
  // What the server does first for every request (Session::handle): the browser-origin rule.
  if (auto refused = api().screen(request)) {
    check_answer(*refused);
    return *refused;
  }
  try {
    api().handle(std::move(request), [answer, answered](http::Response r) {
      if (!answered->exchange(true)) answer->set_value(std::move(r));
    });
  } catch (const std::exception&) {
    RCAND_FUZZ_CHECK(false, "the API handler threw (the server would answer 500)");
  }
  answer.reset();  // the handler's copies alone decide whether an answer can still come
  // Capability handlers answer from their worker within handler_timeout_ms (2 s); a fan-out within 300 ms per peer.
  RCAND_FUZZ_CHECK(future.wait_for(std::chrono::seconds(10)) == std::future_status::ready, "no answer within 10 s");
  try {
    response = future.get();
  } catch (const std::future_error&) {
    RCAND_FUZZ_CHECK(false, "Respond dropped unanswered (the server would answer 500)");
  }
  check_answer(response);
  return response;
}

http::Request owner_request(std::string method, std::string path, std::string body) {
  http::Request request;
  request.method = std::move(method);
  request.target = path;
  request.path = std::move(path);
  request.headers["authorization"] = std::string("Bearer ") + kOwnerToken;
  request.headers["content-type"] = "application/json";
  request.body = std::move(body);
  request.remote = "127.0.0.1:40000";
  return request;
}

std::uint16_t serve_robot() {
  static const std::uint16_t port = robot().instance->start();
  return port;
}

void reset_robot() {
  call(owner_request("POST", "/api/nav/cancel"));
  call(owner_request("POST", "/api/estop/clear"));
}

}  // namespace rcand::fuzz
