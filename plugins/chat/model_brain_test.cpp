// The HTTP brains against scripted model servers on loopback (OpenAI and Ollama wire formats): the request each
// format sends, the answer read back, every fault (500, overload retried, hang, endless stream, garbage, TLS to a
// plain server, refused connection), the API key kept out of every text, the cancel closing the socket, and the
// health probe.
#include <doctest/doctest.h>

#include <cstdlib>
#include <fstream>
#include <thread>

#include "model_answer.hpp"
#include "model_brain.hpp"
#include "scripted_model_server.hpp"

using nlohmann::json;
using namespace rcand::plugins::chat;
using rcand::plugins::chat::testing::ms_between;
using rcand::plugins::chat::testing::ScriptedModelServer;
using std::chrono::milliseconds;
namespace sdk = rcand::sdk;

namespace {

const json kWaypoint{
    {"method", "POST"}, {"path", "/api/nav/waypoint"}, {"body", {{"distance_m", 1}, {"heading_deg", 0}, {"speed", 0.5}}}};

json model_says(json action = kWaypoint, json confidence = 0.9) {
  return {{"reply", "drive forward 1 m"},
          {"reasoning", "the operator said forward one metre"},
          {"action", action},
          {"confidence", confidence}};
}

ModelBrain brain_for(const ScriptedModelServer& server, const char* kind, json extra = json::object()) {
  json block{{"kind", kind}, {"url", server.url()}, {"model", "test-model"}, {"backoff_ms", 20}};
  block.update(extra);
  return ModelBrain(read_model_brain("local", block, ""));
}

sdk::BrainContext brain_context() {
  sdk::BrainContext c;
  c.capabilities = {"status", "teleop", "nav", "chat"};
  c.limits = {{"max_distance_m", 5}};
  return c;
}

sdk::Proposal ask(const ModelBrain& brain, milliseconds budget = milliseconds(3000), std::string image = {}) {
  return brain.propose({"go forward 1 metre", std::move(image), std::chrono::steady_clock::now() + budget}, brain_context(), {});
}

}  // namespace

TEST_CASE("OpenAI wire: chat completions with a json_schema response_format; the answer becomes a proposal") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  server.always(ScriptedModelServer::answer(model_says()));
  ::setenv("RCAND_TEST_OPENAI_KEY", "sk-test-0123456789", 1);
  const auto brain = brain_for(server, "openai", {{"api_key_env", "RCAND_TEST_OPENAI_KEY"}});
  const auto p = ask(brain, milliseconds(3000), "iVBORw0KGgo=");
  REQUIRE_MESSAGE(p.error.empty(), p.error);
  CHECK(p.action == kWaypoint);
  CHECK(p.confidence == 0.9);
  CHECK(p.raw_text == "drive forward 1 m");
  CHECK(p.reasoning == "the operator said forward one metre");
  CHECK(p.brain == "local");
  CHECK(p.model == "test-model");
  REQUIRE(server.posts().size() == 1);
  const auto seen = server.posts()[0];
  CHECK(seen.target == "/v1/chat/completions");
  CHECK(seen.authorization == "Bearer sk-test-0123456789");
  CHECK(seen.body["model"] == "test-model");
  CHECK(seen.body["stream"] == false);
  CHECK(seen.body["response_format"]["type"] == "json_schema");
  CHECK(seen.body["response_format"]["json_schema"]["schema"] == answer_schema());
  CHECK(seen.body["messages"][0]["role"] == "system");
  CHECK(seen.body["messages"][0]["content"].get<std::string>().find("nav") != std::string::npos);
  CHECK(seen.body["messages"][1]["content"][0]["text"] == "go forward 1 metre");
  CHECK(seen.body["messages"][1]["content"][1]["image_url"]["url"] == "data:image/png;base64,iVBORw0KGgo=");
  CHECK(brain.describe().dump().find("sk-test") == std::string::npos);  // status names the source, never the key
  CHECK(brain.describe()["api_key"] == "env RCAND_TEST_OPENAI_KEY");
}

TEST_CASE("Ollama wire: /api/chat with format = the schema, stream false, images; a missing confidence stays missing") {
  ScriptedModelServer server(ScriptedModelServer::Wire::Ollama);
  json said = model_says();
  said.erase("confidence");
  server.always(ScriptedModelServer::answer(said));
  const auto brain = brain_for(server, "ollama");
  const auto p = ask(brain, milliseconds(3000), "/9j/4AAQ");
  REQUIRE_MESSAGE(p.error.empty(), p.error);
  CHECK(p.action == kWaypoint);
  CHECK_FALSE(p.confidence.has_value());  // never a made-up 1.0
  const auto seen = server.posts().at(0);
  CHECK(seen.target == "/api/chat");
  CHECK(seen.authorization.empty());
  CHECK(seen.body["format"] == answer_schema());
  CHECK(seen.body["stream"] == false);
  CHECK(seen.body["messages"][1]["content"] == "go forward 1 metre");
  CHECK(seen.body["messages"][1]["images"] == json::array({"/9j/4AAQ"}));
}

TEST_CASE("a 500 fails at once (no retry); an overloaded server (503) is retried with backoff within the deadline") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  server.always(ScriptedModelServer::fail(500));
  const auto brain = brain_for(server, "openai", {{"retries", 2}});
  auto p = ask(brain);
  CHECK(p.error.find("HTTP 500") != std::string::npos);
  CHECK(p.error.find("scripted failure") != std::string::npos);  // the server's own message, shortened
  CHECK(p.action.is_null());
  CHECK(server.posts().size() == 1);

  server.then(ScriptedModelServer::fail(503));
  server.then(ScriptedModelServer::fail(429));
  server.then(ScriptedModelServer::answer(model_says()));
  p = ask(brain);
  CHECK_MESSAGE(p.error.empty(), p.error);
  const auto posts = server.posts();
  REQUIRE(posts.size() == 4);
  CHECK(ms_between(posts[1].at, posts[2].at) >= 20);  // backoff_ms, then doubled
  CHECK(ms_between(posts[2].at, posts[3].at) >= 40);

  // Retries never run past the deadline: 503s with a backoff longer than the budget give up after one try.
  server.always(ScriptedModelServer::fail(503));
  const auto slow_backoff = brain_for(server, "openai", {{"retries", 5}, {"backoff_ms", 5000}});
  const auto before = std::chrono::steady_clock::now();
  p = slow_backoff.propose({"go", "", before + milliseconds(500)}, brain_context(), {});
  CHECK(p.error.find("HTTP 503") != std::string::npos);
  CHECK(std::chrono::steady_clock::now() - before < milliseconds(400));
}

TEST_CASE("a refused connection is retried, then fails; a hang ends at first_byte_timeout; an endless stream is cut off") {
  std::uint16_t dead_port;
  {
    ScriptedModelServer gone(ScriptedModelServer::Wire::OpenAI);
    dead_port = gone.port();
  }
  const auto refused = ModelBrain(read_model_brain("local",
                                                   {{"kind", "openai"},
                                                    {"url", "http://127.0.0.1:" + std::to_string(dead_port)},
                                                    {"model", "m"},
                                                    {"backoff_ms", 10},
                                                    {"retries", 2}},
                                                   ""));
  auto p = ask(refused);
  CHECK(p.error.find("connect failed") != std::string::npos);
  CHECK(p.error.find("after 3 tries") != std::string::npos);

  ScriptedModelServer server(ScriptedModelServer::Wire::Ollama);
  server.always(ScriptedModelServer::hang());
  const auto brain = brain_for(server, "ollama", {{"first_byte_timeout_ms", 200}});
  auto before = std::chrono::steady_clock::now();
  p = ask(brain);
  auto took = std::chrono::steady_clock::now() - before;
  CHECK(p.error.find("first_byte_timeout_ms") != std::string::npos);
  CHECK(took >= milliseconds(190));
  CHECK(took < milliseconds(1000));
  CHECK(server.posts().size() == 1);  // a timeout after sending is not retried (the model may be running)
  CHECK(server.wait_for_closes(1));

  server.always(ScriptedModelServer::endless());
  before = std::chrono::steady_clock::now();
  p = brain_for(server, "ollama", {{"max_answer_bytes", 65536}})
          .propose({"go", "", before + milliseconds(3000)}, brain_context(), {});
  CHECK(p.error.find("exceeded 65536 bytes") != std::string::npos);
  CHECK(std::chrono::steady_clock::now() - before < milliseconds(1000));
}

TEST_CASE("bad answers are the brain failing: not JSON, off-schema, a confidence outside [0, 1], an action that is no request") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  const auto brain = brain_for(server, "openai");
  server.always(ScriptedModelServer::malformed());
  CHECK(ask(brain).error == "the model's answer is not JSON");
  const std::vector<std::pair<json, std::string>> cases = {
      {model_says(kWaypoint, 1.7), "confidence"},     {model_says(kWaypoint, "high"), "confidence"},
      {model_says("drive forward"), "not a request"}, {model_says(json{{"path", "/api/stop"}}), "not a request"},
      {json::array({1, 2}), "not a JSON object"},     {json{{"reply", "hi"}}, "no action"},
  };
  for (const auto& item : cases) {  // not a structured binding: CHECK_MESSAGE makes a lambda (clang 14)
    const json& answer = item.first;
    const std::string& why = item.second;
    server.always(ScriptedModelServer::answer(answer));
    const auto p = ask(brain);
    CHECK_MESSAGE(p.error.find(why) != std::string::npos, answer.dump() << " -> " << p.error);
    CHECK(p.action.is_null());
  }
  // The model's text is read by chat's action check afterwards: an undeclared capability or out-of-bounds numbers
  // come back as a proposal here and are refused there (chat_test).
  server.always(ScriptedModelServer::answer(model_says({{"method", "POST"}, {"path", "/api/cap/com.evil/fire"}})));
  CHECK(ask(brain).error.empty());
}

TEST_CASE("https to a server that does not speak TLS fails the handshake; a certificate is always verified") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  const auto brain = ModelBrain(read_model_brain(
      "hosted", {{"kind", "openai"}, {"url", "https://127.0.0.1:" + std::to_string(server.port()) + "/v1"}, {"model", "m"}}, ""));
  const auto p = ask(brain);
  CHECK(p.error.find("TLS handshake failed") != std::string::npos);
  CHECK(server.posts().empty());  // nothing was sent in the clear
  CHECK_THROWS_AS(ModelBrain(read_model_brain(
                      "x", {{"kind", "openai"}, {"url", "https://h/v1"}, {"model", "m"}, {"ca_file", "/nonexistent.pem"}}, "")),
                  rcand::sdk::ConfigError);
}

TEST_CASE("the API key never appears in an error, a log line or status, even when the server echoes it") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  server.always(ScriptedModelServer::echo_key(401));
  const std::string key_file = "/tmp/rcand-chat-test-key-" + std::to_string(::getpid());
  std::ofstream(key_file) << "sk-secret-abcdef0123456789\n";
  const auto brain = brain_for(server, "openai", {{"api_key_file", key_file}});
  const auto p = ask(brain);
  std::remove(key_file.c_str());
  CHECK(server.posts().at(0).authorization == "Bearer sk-secret-abcdef0123456789");
  CHECK(p.error.find("HTTP 401") != std::string::npos);
  CHECK(p.error.find("sk-secret") == std::string::npos);
  CHECK(p.error.find("[api key]") != std::string::npos);
  CHECK(brain.describe().dump().find("sk-secret") == std::string::npos);

  const auto unset =
      ModelBrain(read_model_brain("x", {{"kind", "ollama"}, {"model", "m"}, {"api_key_env", "RCAND_TEST_NO_SUCH_VAR"}}, ""));
  CHECK(ask(unset).error.find("RCAND_TEST_NO_SUCH_VAR") != std::string::npos);
  CHECK_THROWS_AS(read_model_brain("x", {{"kind", "ollama"}, {"model", "m"}, {"api_key_env", "A"}, {"api_key_file", "/b"}}, ""),
                  rcand::sdk::ConfigError);
}

TEST_CASE("a cancel closes the brain's socket at once, during the wait for a slow model") {
  ScriptedModelServer server(ScriptedModelServer::Wire::OpenAI);
  server.always(ScriptedModelServer::hang());
  const auto brain = brain_for(server, "openai");
  sdk::CancelToken cancel;
  sdk::Proposal p;
  std::thread call([&] {
    p = brain.propose({"go", "", std::chrono::steady_clock::now() + milliseconds(10000)}, brain_context(), cancel);
  });
  REQUIRE(server.wait_for_posts(1));
  const auto cancelled_at = std::chrono::steady_clock::now();
  cancel.cancel();
  REQUIRE(server.wait_for_closes(1));
  call.join();
  const double ms = ms_between(cancelled_at, server.posts()[0].closed);
  MESSAGE("cancel -> the server saw the socket close: " << ms << " ms");
  // The request's deadline is 10 s away: closed well before it, the cancel closed it. How fast is a figure, not a
  // test (bench/chat_stop_bench.cpp "stop sent -> brain socket closed", README): 13 ms was seen here under load.
  CHECK(ms < 1000.0);
  CHECK(p.error == "cancelled");
  CHECK(p.action.is_null());

  // Cancelled before the call: nothing is sent.
  p = brain.propose({"go", "", std::chrono::steady_clock::now() + milliseconds(1000)}, brain_context(), cancel);
  CHECK(p.error == "cancelled");
  CHECK(server.posts().size() == 1);
}

TEST_CASE("the health probe: the server's model list, a failing server, a dead one") {
  ScriptedModelServer openai(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer ollama(ScriptedModelServer::Wire::Ollama);
  auto h = brain_for(openai, "openai").probe(milliseconds(1000), {});
  CHECK(h["ok"] == true);
  CHECK(h["model_listed"] == true);
  CHECK(h["latency_ms"].is_number());
  const auto ollama_brain = brain_for(ollama, "ollama");
  CHECK(ollama_brain.probe(milliseconds(1000), {})["model_listed"] == true);  // "test-model:latest"
  CHECK(ollama_brain.health()["ok"] == true);
  ollama.health_fails(true);
  h = ollama_brain.probe(milliseconds(1000), {});
  CHECK(h["ok"] == false);
  CHECK(h["status"] == 503);
  CHECK(ollama_brain.describe()["health"]["ok"] == false);
  const auto dead = ModelBrain(read_model_brain("x", {{"kind", "ollama"}, {"url", "http://127.0.0.1:1"}, {"model", "m"}}, ""));
  CHECK(dead.probe(milliseconds(500), {})["ok"] == false);
}

TEST_CASE("brain settings: endpoints, defaults, and errors naming the key") {
  std::string why;
  auto e = parse_endpoint("https://api.example.com/v1/", why);
  REQUIRE(e);
  CHECK(e->tls);
  CHECK(e->port == "443");
  CHECK(e->base_path == "/v1");
  e = parse_endpoint("http://[::1]:8080", why);
  REQUIRE(e);
  CHECK(e->host == "::1");
  CHECK(e->port == "8080");
  for (const char* bad : {"ftp://x", "http://", "http://user@host", "http://h:99999", "http://h/x?y=1"})
    CHECK_MESSAGE(!parse_endpoint(bad, why), bad);

  const auto ollama = read_model_brain("ollama", nullptr, "llama3.2");
  CHECK(ollama.url == "http://127.0.0.1:11434");
  CHECK(ollama.model == "llama3.2");
  CHECK(read_model_brain("openai", nullptr, "gpt-4o-mini").endpoint.host == "api.openai.com");
  CHECK_THROWS_AS(read_model_brain("mine", json::object(), "m"), rcand::sdk::ConfigError);  // no kind
  CHECK_THROWS_AS(read_model_brain("ollama", nullptr, ""), rcand::sdk::ConfigError);        // no model
  CHECK_THROWS_AS(read_model_brain("ollama", {{"timeout", 5}}, "m"), rcand::sdk::ConfigError);
  CHECK_THROWS_AS(read_model_brain("ollama", {{"retries", 50}}, "m"), rcand::sdk::ConfigError);
}
