// libFuzzer target: a model server's answer, through chat's HTTP brain (plugins/chat/model_brain.cpp: Beast reading
// the answer in HttpExchange, the OpenAI-compatible or Ollama envelope, read_model_answer) and then chat's action
// check (check_action) with the sim rover's limits. A loopback server answers the brain's POST with the fuzzer's
// bytes and closes. The first byte picks the wire format (bit 0: OpenAI or Ollama) and what the rest is (bits 1..2):
//   0  the whole HTTP answer, status line and headers included (chunked, cut short, 429 then a retry, 100 Continue...)
//   1  the body of a 200 answer (the server's JSON envelope)
//   2  the model's content: wrapped in a well-formed envelope of the format, so mutations land in the answer schema
//   3  as 2, with a refusal next to the content (OpenAI's message.refusal)
// Invariants: propose() returns (no hang: every wait is bounded by the brain's timeouts); a failed proposal has an
// error and no action; a confidence lies in [0, 1]; the API key (which the fuzzer may echo back) is in none of the
// error, the reply or the reasoning; the action check either returns a checked action inside the robot's bounds or
// refuses it with 404 CAPABILITY_NOT_FOUND / 422 ACTION_REJECTED naming "action".
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <variant>

#include <nlohmann/json.hpp>

#include "fuzz_check.hpp"
#include "plugins/chat/action_check.hpp"
#include "plugins/chat/model_brain.hpp"

namespace {

using nlohmann::json;
namespace chat = rcand::plugins::chat;

constexpr const char* kApiKey = "sk-fuzz-3f9a1c2e7b";  // also in dict/model.dict, so the fuzzer can echo it
constexpr const char* kKeyEnv = "RCAND_FUZZ_MODEL_KEY";

// A model server on 127.0.0.1: each connection gets the current answer's bytes, then the server closes its side.
class LoopbackServer {
 public:
  LoopbackServer() {
    listener_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    RCAND_FUZZ_CHECK(listener_ >= 0, "cannot open the loopback server's socket");
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof address;
    RCAND_FUZZ_CHECK(::bind(listener_, reinterpret_cast<sockaddr*>(&address), length) == 0 && ::listen(listener_, 16) == 0 &&
                         ::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length) == 0,
                     "cannot listen on loopback");
    port_ = ntohs(address.sin_port);
    std::thread([this] { serve(); }).detach();  // lives as long as the process
  }
  std::uint16_t port() const { return port_; }
  void set_answer(std::string bytes) {
    std::lock_guard lock(mutex_);
    answer_ = std::move(bytes);
  }

 private:
  void serve() {
    for (;;) {
      const int fd = ::accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd < 0) continue;
      read_request(fd);
      std::string answer;
      {
        std::lock_guard lock(mutex_);
        answer = answer_;
      }
      for (std::size_t sent = 0; sent < answer.size();) {
        const ssize_t n = ::send(fd, answer.data() + sent, answer.size() - sent, MSG_NOSIGNAL);
        if (n <= 0) break;
        sent += static_cast<std::size_t>(n);
      }
      ::shutdown(fd, SHUT_WR);
      drain(fd, 2000);  // until the brain closes: closing with its bytes unread would reset the answer away
      ::close(fd);
    }
  }
  // The request's header and Content-Length bytes of body (the brain always sends one).
  static void read_request(int fd) {
    std::string request;
    char chunk[4096];
    std::size_t need = std::string::npos;
    while (need == std::string::npos || request.size() < need) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 2000) <= 0) return;
      const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
      if (n <= 0) return;
      request.append(chunk, static_cast<std::size_t>(n));
      const auto end = request.find("\r\n\r\n");
      if (need == std::string::npos && end != std::string::npos) {
        std::size_t body = 0;
        for (const char* name : {"Content-Length: ", "content-length: "})
          if (const auto at = request.find(name); at != std::string::npos && at < end)
            body = std::strtoul(request.c_str() + at + std::string_view(name).size(), nullptr, 10);
        need = end + 4 + body;
      }
    }
  }
  static void drain(int fd, int timeout_ms) {
    char chunk[4096];
    for (;;) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, timeout_ms) <= 0 || ::recv(fd, chunk, sizeof chunk, 0) <= 0) return;
    }
  }

  int listener_ = -1;
  std::uint16_t port_ = 0;
  std::mutex mutex_;
  std::string answer_;
};

LoopbackServer& server() {
  static LoopbackServer* instance = new LoopbackServer;
  return *instance;
}

const chat::ModelBrain& brain(bool ollama) {
  // Through the config reader chat uses: short timeouts (the server always closes at once), one quick retry after
  // an overloaded answer, and a small answer limit so the fuzzer reaches it.
  auto make = [](const char* kind) {
    ::setenv(kKeyEnv, kApiKey, 1);
    const json block{
        {"kind", kind},
        {"url", "http://127.0.0.1:" + std::to_string(server().port()) + (std::string(kind) == "openai" ? "/v1" : "")},
        {"model", "fuzz-model"},
        {"api_key_env", kKeyEnv},
        {"timeout_ms", 5000},
        {"connect_timeout_ms", 1000},
        {"first_byte_timeout_ms", 5000},
        {"retries", 1},
        {"backoff_ms", 1},
        {"max_answer_bytes", 2048}};
    return new chat::ModelBrain(chat::read_model_brain(kind, block, ""));
  };
  static const chat::ModelBrain* openai = make("openai");
  static const chat::ModelBrain* ollama_brain = make("ollama");
  return ollama ? *ollama_brain : *openai;
}

// The sim rover's bounds (config/sim-rover.rcan.yaml) as chat_settings.cpp reads them.
const chat::ActionLimits& limits() {
  static const chat::ActionLimits* l = [] {
    auto* out = new chat::ActionLimits;
    out->declared = {"status", "teleop", "nav", "vision", "arm", "chat", "com.acme.gripper"};
    out->wheel_circumference_m = 0.21;
    out->turn_time_per_deg_s = 0.008;
    out->max_wheel_rps = 1.0;
    return out;
  }();
  return *l;
}

std::string http_answer(std::string_view body) {
  return "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" +
         std::string(body);
}

std::string envelope(bool ollama, std::string_view content, bool refusal) {
  json message{{"role", "assistant"}, {"content", std::string(content)}};
  if (refusal) message["refusal"] = "I cannot help with that";
  const json body = ollama ? json{{"model", "fuzz-model"}, {"message", message}, {"done", true}}
                           : json{{"id", "chatcmpl-fuzz"},
                                  {"object", "chat.completion"},
                                  {"choices", json::array({{{"index", 0}, {"message", message}, {"finish_reason", "stop"}}})}};
  return body.dump(-1, ' ', false, json::error_handler_t::replace);
}

bool quotes_key(const std::string& text) { return text.find(kApiKey) != std::string::npos; }

void check_checked(const chat::CheckedAction& c, const chat::ActionLimits& l) {
  RCAND_FUZZ_CHECK(c.method == "GET" || c.method == "POST", "a checked action is a GET or a POST");
  RCAND_FUZZ_CHECK(c.path.rfind("/api/", 0) == 0 && c.path.find("..") == std::string::npos &&
                       c.path.find_first_of("?#%\\ ") == std::string::npos,
                   "a checked action's path is a plain /api/ path");
  RCAND_FUZZ_CHECK(c.capability != "chat", "chat never dispatches to itself");
  if (c.capability.empty())
    RCAND_FUZZ_CHECK((c.method == "POST" && c.path == "/api/stop") || (c.method == "GET" && c.path == "/api/status"),
                     "only the stop and the status are rcand's own routes a brain may use");
  else
    RCAND_FUZZ_CHECK(std::find(l.declared.begin(), l.declared.end(), c.capability) != l.declared.end(),
                     "a checked action needs a declared capability");
  RCAND_FUZZ_CHECK(c.method == "POST" || (!c.motion && c.body.is_null()), "a GET moves nothing and has no body");
  RCAND_FUZZ_CHECK(!c.stop || c.path == "/api/stop", "only POST /api/stop is the stop");
  if (c.path == "/api/action" && c.body.value("type", json()) == "move") {
    const json& d = c.body.at("duration_ms");
    RCAND_FUZZ_CHECK(d.is_number_integer() && d.get<double>() >= 1 && d.get<double>() <= l.max_duration_ms,
                     "a brain's move ends by itself within max_duration_ms");
    for (const char* key : {"linear", "angular"})
      if (c.body.contains(key))
        RCAND_FUZZ_CHECK(std::abs(c.body.at(key).get<double>()) <= (std::string(key) == "linear" ? l.max_linear_speed : 1.0),
                         "a brain's move stays inside the speed bounds");
  }
  if (c.method == "POST" && c.path == "/api/nav/waypoint")
    RCAND_FUZZ_CHECK(std::abs(c.body.at("distance_m").get<double>()) <= l.max_distance_m &&
                         std::abs(c.body.at("heading_deg").get<double>()) <= l.max_turn_deg,
                     "a brain's waypoint stays inside chat's bounds");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const bool ollama = (data[0] & 1) != 0;
  const int mode = (data[0] >> 1) & 3;
  const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  server().set_answer(mode == 0 ? std::string(rest)
                                : http_answer(mode == 1 ? std::string(rest) : envelope(ollama, rest, mode == 3)));

  rcand::sdk::BrainRequest request;
  request.instruction = "drive forward one metre";
  request.deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  rcand::sdk::BrainContext context;
  context.capabilities = limits().declared;
  const rcand::sdk::Proposal p = brain(ollama).propose(request, context, rcand::sdk::CancelToken());

  RCAND_FUZZ_CHECK(p.error.empty() || p.action.is_null(), "a failed proposal carries no action");
  RCAND_FUZZ_CHECK(!p.confidence || (*p.confidence >= 0 && *p.confidence <= 1), "a confidence lies in [0, 1]");
  RCAND_FUZZ_CHECK(!quotes_key(p.error) && !quotes_key(p.raw_text) && !quotes_key(p.reasoning),
                   "the API key is in no error, reply or reasoning");
  RCAND_FUZZ_CHECK(p.suggestions.size() <= 3, "at most three suggestions");
  if (p.action.is_null()) return 0;
  const auto checked = chat::check_action(p.action, limits());
  if (const auto* c = std::get_if<chat::CheckedAction>(&checked)) {
    check_checked(*c, limits());
  } else {
    const auto& refusal = std::get<rcand::sdk::Response>(checked);
    RCAND_FUZZ_CHECK(refusal.status == 404 || refusal.status == 422, "a refused action is 404 or 422");
    RCAND_FUZZ_CHECK(refusal.body.value("field", "") == "action" && (refusal.body.value("code", "") == "CAPABILITY_NOT_FOUND" ||
                                                                     refusal.body.value("code", "") == "ACTION_REJECTED"),
                     "a refusal names the action and its code");
  }
  return 0;
}
