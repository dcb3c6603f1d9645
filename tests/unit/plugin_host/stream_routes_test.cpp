// Stream routes (SDK 1.2, rcand/sdk/stream.hpp) through a real kernel's route table and middleware: a body, a
// multipart stream pushed from another thread, a JSON refusal, the scope of a custom capability, the handler timeout
// for a handler that never answers (503, the capability stays up), a dropped writer (500), a throwing handler (500,
// failed), and a plugin that declares minor 1, whose stream_routes() the kernel must never call.
#include <doctest/doctest.h>

#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>

#include "kernel/api/api.hpp"
#include "kernel/kernel.hpp"
#include "libs/http/response_stream.hpp"
#include "libs/rcan/crypto.hpp"

using namespace rcand;
using namespace rcand::kernel;
using nlohmann::json;

namespace {

namespace fs = std::filesystem;
const fs::path kStreamFixtures = RCAND_TEST_PLUGIN_DIR;
const std::string kStreamOwner = "stream-routes-test-owner";
const std::string kStreamGuest = "stream-routes-test-guest";

config::RobotConfig streamer_robot() {
  const std::string yaml = R"(rcan_version: "1.3"
metadata: {robot_name: streamer, robot_uuid: "7a1b2c3e", manufacturer: rcand, model: fixture}
rcan_protocol:
  port: 8000
  enable_mdns: false
  enable_jwt: false
  capabilities: [status, org.rcand.test.stream_current, org.rcand.test.stream_minor_one]
runtime:
  listen: {address: 127.0.0.1, port: 0}
  plugin_paths: [")" + (kStreamFixtures / "streams").string() +
                           R"("]
  swarm_file: /nonexistent/swarm.yaml
  handler_timeout_ms: 300
  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}
  auth:
    tokens:
      - {principal: owner, role: owner, sha256: )" +
                           sha256_hex(kStreamOwner) + R"(}
      - {principal: guest, role: guest, sha256: )" +
                           sha256_hex(kStreamGuest) + "}\n";
  return config::parse_robot_config(yaml, "streamer.rcan.yaml", "/").config;
}

http::Response stream_call(Api& api, const std::string& path, const std::string& token = kStreamOwner) {
  http::Request request;
  request.method = "GET";
  request.target = request.path = path;
  request.headers["authorization"] = "Bearer " + token;
  request.remote = "127.0.0.1:1";
  std::mutex mutex;
  std::condition_variable cv;
  std::optional<http::Response> answer;
  api.handle(std::move(request), [&](http::Response response) {
    std::lock_guard lock(mutex);
    answer = std::move(response);
    cv.notify_all();
  });
  std::unique_lock lock(mutex);
  REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answer.has_value(); }));
  return std::move(*answer);
}

// Every part of a streamed answer until its end, as the Session would take them.
std::vector<std::string> drain_stream(http::ResponseStream& stream) {
  std::mutex mutex;
  std::condition_variable woken;
  bool wake = false;
  stream.attach([&] {
    std::lock_guard lock(mutex);
    wake = true;
    woken.notify_all();
  });
  std::vector<std::string> parts;
  http::ResponseStream::Part part;
  while (true) {
    const auto next = stream.next(part);
    if (next == http::ResponseStream::Next::End) break;
    if (next == http::ResponseStream::Next::Part) {
      parts.push_back(part.head + *part.data + part.tail);
      stream.written(part.data->size());
      continue;
    }
    std::unique_lock lock(mutex);
    REQUIRE(woken.wait_for(lock, std::chrono::seconds(5), [&] { return wake; }));
    wake = false;
  }
  stream.close();
  return parts;
}

std::string header_of(const http::Response& response, const std::string& name) {
  for (const auto& [key, value] : response.headers)
    if (key == name) return value;
  return {};
}

}  // namespace

TEST_CASE("stream routes through a real kernel: bodies, streams, refusals, timeouts and failures") {
  Kernel kernel(streamer_robot(), embedded_kernel_options());
  for (const auto& record : kernel.plugins().records()) {
    CAPTURE(record->id);
    CHECK(to_string(record->state) == to_string(PluginState::Loaded));
  }
  Api& api = kernel.api();
  const std::string base = "/api/cap/org.rcand.test.stream_current";

  const auto bytes = stream_call(api, base + "/bytes");
  CHECK(bytes.status == 200);
  CHECK(bytes.content_type == "application/octet-stream");
  CHECK(bytes.body == "stream-ok");
  CHECK(header_of(bytes, "X-Fixture") == "1");
  CHECK_FALSE(header_of(bytes, "X-Message-Id").empty());  // the middleware's, as on every answer

  auto parts = stream_call(api, base + "/parts");
  CHECK(parts.status == 200);
  CHECK(parts.content_type == "multipart/x-mixed-replace; boundary=rcandframe");
  REQUIRE(parts.stream);
  const auto received = drain_stream(*parts.stream);
  REQUIRE_FALSE(received.empty());  // a part pushed before the previous one was taken replaces it
  CHECK(received.back() == "--rcandframe\r\nContent-Type: text/plain\r\nContent-Length: 6\r\n\r\npart-3\r\n");

  const auto refused = stream_call(api, base + "/refuse");
  CHECK(refused.status == 503);
  CHECK(header_of(refused, "Retry-After") == "5");
  CHECK(json::parse(refused.body) == json{{"error", "full"}, {"code", "UNAVAILABLE"}, {"status", 503}, {"limit", 1}});

  CHECK(stream_call(api, base + "/bytes", kStreamGuest).status == 403);  // a custom capability's routes need control (§9.4)

  const auto silent = stream_call(api, base + "/silent");  // answered by the timeout (300 ms)
  CHECK(silent.status == 503);
  CHECK(json::parse(silent.body)["error"].get<std::string>().find("did not start its answer") != std::string::npos);
  CHECK(stream_call(api, base + "/ping").status == 200);  // the handler returned: the capability is not failed

  CHECK(stream_call(api, base + "/drop").status == 500);
  CHECK(stream_call(api, base + "/ping").status == 200);

  CHECK(stream_call(api, base + "/throw").status == 500);
  CHECK(stream_call(api, base + "/throw").status == 500);  // every time: the request fails, not the capability
  CHECK(stream_call(api, base + "/ping").status == 200);   // docs/protocol.md §7.16
}

TEST_CASE("a plugin that declares ABI minor 1 keeps its JSON routes, and the kernel never calls stream_routes()") {
  Kernel kernel(streamer_robot(), embedded_kernel_options());
  Api& api = kernel.api();
  const std::string base = "/api/cap/org.rcand.test.stream_minor_one";
  CHECK(stream_call(api, base + "/ping").status == 200);  // its stream_routes() throws: had it been called, it would be failed
  CHECK(stream_call(api, base + "/bytes").status == 404);
  const auto status = json::parse(stream_call(api, "/api/status").body);
  CHECK(status["capabilities"]["org.rcand.test.stream_minor_one"]["state"] == "ok");
}
