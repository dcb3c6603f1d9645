// libFuzzer target: JSON bodies of every endpoint that reads one, authorized as the owner, through the real Api of
// a simulated robot. The first byte picks the endpoint; the rest is the body. Swarm fields ("broadcast", "nodes",
// "tags") ride in the bodies of /api/stop and /api/command.
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <string>

#include "sim_robot.hpp"

namespace {

struct Endpoint {
  const char* method;
  const char* path;
  bool broadcast_header;  // X-Swarm-Broadcast: true
};

constexpr Endpoint kEndpoints[] = {
    {"POST", "/api/action", false},
    {"POST", "/api/nav/waypoint", false},
    {"POST", "/api/nav/cancel", false},
    {"POST", "/api/command", false},
    {"POST", "/api/command", true},
    {"POST", "/api/stop", false},
    {"POST", "/api/stop", true},
    {"POST", "/api/estop/clear", false},
    {"POST", "/api/cap/com.acme.gripper/grip", false},
    {"GET", "/api/cap/com.acme.gripper/state", false},
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const Endpoint& endpoint = kEndpoints[data[0] % std::size(kEndpoints)];
  auto request = rcand::fuzz::owner_request(endpoint.method, endpoint.path,
                                            std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  if (endpoint.broadcast_header) request.headers["x-swarm-broadcast"] = "true";
  rcand::fuzz::call(std::move(request));
  rcand::fuzz::reset_robot();
  return 0;
}
