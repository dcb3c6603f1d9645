// POST /api/stop while chat's brains are busy (issue 16): a real rcand whose chat brain is an OpenAI-compatible
// scripted model server on loopback. Each loaded sample puts five instructions in flight - four whose model answers
// after 2 s and one whose model never answers - waits until the server has read all five requests and then a random
// 2-20 ms (a stop lands anywhere in a model call), then times one
// POST /api/stop on a kept-alive connection, and records when the server saw each brain socket close. Idle samples
// time the same stop with nothing in flight. The e-stop is cleared between samples.
//   bench_chat_stop [SAMPLES]
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../plugins/chat/scripted_model_server.hpp"
#include "libs/http/client.hpp"
#include "rcand_process.hpp"

namespace {

using nlohmann::json;
using rcand::plugins::chat::testing::ScriptedModelServer;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

void report(const char* what, const std::vector<double>& ms) {
  std::printf("%-34s n=%zu  p50 %.3f  p90 %.3f  p99 %.3f  max %.3f ms\n", what, ms.size(), percentile(ms, 0.5),
              percentile(ms, 0.9), percentile(ms, 0.99), *std::max_element(ms.begin(), ms.end()));
}

const std::map<std::string, std::string> kOwner{{"Authorization", "Bearer owner-token"}};

// The client's time for the whole exchange; `server_ms` gets rcand's own (latency_us in the answer).
double timed_stop(rcand::http::Client& client, std::vector<double>& server_ms) {
  const auto before = Clock::now();
  const auto answer = client.request("POST", "/api/stop", "", kOwner);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - before).count();
  if (answer.status != 200) throw std::runtime_error("POST /api/stop answered " + std::to_string(answer.status));
  server_ms.push_back(json::parse(answer.body).value("latency_us", 0.0) / 1000.0);
  return ms;
}

void clear(rcand::http::Client& client) {
  if (client.request("POST", "/api/estop/clear", "", kOwner).status != 200) throw std::runtime_error("clear refused");
}

}  // namespace

int main(int argc, char** argv) {
  const int samples = argc > 1 ? std::max(10, std::atoi(argv[1])) : 200;
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  auto config = rcand::test::sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "chat"};
  config["agent"] = {{"provider", "local"}, {"model", "bench-model"}};
  config["runtime"]["capabilities"]["chat"] = {
      {"workers", 5},
      {"brains", {{"local", {{"kind", "openai"}, {"url", server.url()}, {"model", "bench-model"}, {"retries", 0}}}}}};
  config["runtime"]["logging"]["level"] = "warn";
  rcand::test::RcandProcess rcand(config);
  rcand::http::Client client("127.0.0.1", rcand.port());
  const json move{
      {"reply", "driving"},
      {"action",
       {{"method", "POST"}, {"path", "/api/action"}, {"body", {{"type", "move"}, {"linear", 0.3}, {"duration_ms", 2000}}}}},
      {"confidence", 0.9}};

  std::vector<double> idle, loaded, socket_closed, idle_server, loaded_server;
  for (int i = 0; i < samples; ++i) {  // warm and idle
    idle.push_back(timed_stop(client, idle_server));
    clear(client);
  }
  std::size_t posts = 0;
  std::mt19937 random(12345);
  std::uniform_int_distribution<int> settle(2000, 20000);
  for (int i = 0; i < samples; ++i) {
    for (int k = 0; k < 4; ++k) server.then(ScriptedModelServer::answer(move, std::chrono::milliseconds(2000)));
    server.then(ScriptedModelServer::hang());
    std::vector<std::thread> callers;
    for (int k = 0; k < 5; ++k)
      callers.emplace_back([&] { rcand.request("POST", "/api/command", "user-token", R"({"instruction":"drive on"})"); });
    posts += 5;
    if (!server.wait_for_posts(posts)) throw std::runtime_error("the brain calls did not reach the model server");
    // A stop comes at any moment of a 2 s model call, not in the same millisecond as the five requests: waiting a
    // random 2-20 ms keeps this harness's own threads (the callers, the model server reading the posts) from being
    // timed as the stop's cost, while the calls stay in flight.
    std::this_thread::sleep_for(std::chrono::microseconds(settle(random)));
    const auto sent = Clock::now();
    loaded.push_back(timed_stop(client, loaded_server));
    if (!server.wait_for_closes(posts, std::chrono::milliseconds(2000))) throw std::runtime_error("a brain socket stayed open");
    const auto seen = server.posts();
    for (std::size_t k = posts - 5; k < posts; ++k)
      socket_closed.push_back(std::chrono::duration<double, std::milli>(seen[k].closed - sent).count());
    for (auto& t : callers) t.join();
    clear(client);
  }
  std::printf("POST /api/stop on a real rcand, kept-alive connection, %d samples each\n", samples);
  report("idle (client)", idle);
  report("4 x 2 s + 1 hung brain call (client)", loaded);
  report("idle (rcand's latency_us)", idle_server);
  report("loaded (rcand's latency_us)", loaded_server);
  report("stop sent -> brain socket closed", socket_closed);
  const auto status = rcand.json("GET", "/api/status", "owner-token")["capabilities"]["chat"]["status"];
  std::printf("chat: %s dispatched, %s cancelled\n", status["dispatched"].dump().c_str(), status["cancelled"].dump().c_str());
  return 0;
}
