// The brain chain with HTTP brains against scripted model servers: agent.provider -> agent.fallbacks -> the grammar
// brain, the switch time on a 500 and on a hang, the deadline kept below runtime.handler_timeout_ms, and the API key
// kept out of chat's answers and logs.
#include <cstdlib>

#include "chat_fixture.hpp"
#include "scripted_model_server.hpp"

using namespace chat_test;
using rcand::plugins::chat::testing::ms_between;
using rcand::plugins::chat::testing::ScriptedModelServer;
using std::chrono::milliseconds;

namespace {

json answer_with(json action, double confidence = 0.9) {
  return {{"reply", "as you say"}, {"reasoning", "because"}, {"action", std::move(action)}, {"confidence", confidence}};
}

json brains(const ScriptedModelServer& primary, const ScriptedModelServer& backup, json primary_extra = json::object()) {
  json p{{"kind", "openai"}, {"url", primary.url()}, {"model", "primary-model"}, {"retries", 0}};
  p.update(primary_extra);
  return {{"brains", {{"primary", p}, {"backup", {{"kind", "ollama"}, {"url", backup.url()}, {"model", "backup-model"}}}}}};
}

json chain_agent() { return {{"provider", "primary"}, {"fallbacks", {{{"provider", "backup"}}}}}; }

}  // namespace

TEST_CASE("fallback chain: a 500 from agent.provider switches to the fallback in < 50 ms; answer and thought name it") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  primary.always(ScriptedModelServer::fail(500));
  backup.always(ScriptedModelServer::answer(answer_with(waypoint(1, 0))));
  Fixture f(rover_config(brains(primary, backup), chain_agent()));
  f.host.run_pending();  // the health probes chat starts with
  CHECK(f.chat().status()["brains"]["primary"]["health"]["ok"] == true);

  const auto w = f.say("go forward 1 metre");
  REQUIRE(w->status() == 200);
  const json a = w->json();
  CHECK(a["brain"] == "backup");
  CHECK(a["model"] == "backup-model");
  CHECK(a["request"] == waypoint(1, 0));
  REQUIRE(a["attempts"].size() == 2);
  CHECK(a["attempts"][0]["brain"] == "primary");
  CHECK(a["attempts"][0]["error"].get<std::string>().find("HTTP 500") != std::string::npos);
  REQUIRE(f.dispatcher.requests.size() == 1);
  const double switch_ms = ms_between(primary.posts().at(0).answered, backup.posts().at(0).at);
  MESSAGE("500 written -> the fallback's request read: " << switch_ms << " ms");
  CHECK(switch_ms < 50.0);

  const auto thought = f.get("/api/thoughts/" + a["thought_id"].get<std::string>());
  REQUIRE(thought.status == 200);
  CHECK(thought.body["brain"] == "backup");
  CHECK(thought.body["attempts"].size() == 2);
  CHECK(thought.body["state"] == "dispatched");
}

TEST_CASE("chat's HTTP brains are Brain services found by name; a name another plugin offers fails chat's start") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  backup.always(ScriptedModelServer::answer(answer_with(waypoint(1, 0))));
  {
    Fixture f(rover_config(brains(primary, backup), chain_agent()));
    const auto* found = static_cast<const sdk::Brain*>(f.host.service(sdk::brain_service_id("backup")));
    REQUIRE(found != nullptr);
    CHECK(found->provider() == "backup");
    CHECK(f.host.service(sdk::brain_service_id("primary")) != nullptr);
    CHECK(f.host.service(sdk::brain_service_id("grammar")) == nullptr);  // embedded in chat, always last
  }

  FakeHost host(rover_config(brains(primary, backup), chain_agent()));
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  SpyBrain other;
  REQUIRE(host.offer_service(sdk::brain_service_id("backup"), static_cast<const sdk::Brain*>(&other)));
  CHECK_THROWS_WITH_AS(host.add_capability("chat"),
                       doctest::Contains("brain 'backup' is configured in runtime.capabilities.chat.brains and offered by "
                                         "another plugin too"),
                       rcand::sdk::testing::HostError);
}

TEST_CASE("fallback chain: a hung provider is dropped at its first_byte_timeout and the fallback starts < 50 ms later") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  primary.always(ScriptedModelServer::hang());
  backup.always(ScriptedModelServer::answer(answer_with(waypoint(0, 90))));
  Fixture f(rover_config(brains(primary, backup, {{"first_byte_timeout_ms", 300}}), chain_agent()));
  const auto w = f.say("turn left");
  REQUIRE(w->status() == 200);
  CHECK(w->json()["brain"] == "backup");
  REQUIRE(primary.wait_for_closes(1));
  const double switch_ms = ms_between(primary.posts().at(0).closed, backup.posts().at(0).at);
  MESSAGE("hung socket closed -> the fallback's request read: " << switch_ms << " ms");
  CHECK(switch_ms < 50.0);
  CHECK(ms_between(primary.posts()[0].at, primary.posts()[0].closed) >= 290);
}

TEST_CASE("fallback chain: every HTTP brain failing (garbage, endless) leaves the grammar brain, which always answers") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  primary.always(ScriptedModelServer::malformed());
  backup.always(ScriptedModelServer::endless());
  Fixture f(rover_config(brains(primary, backup), chain_agent()));
  const auto w = f.say("go forward 1 metre");
  REQUIRE(w->status() == 200);
  CHECK(w->json()["brain"] == "grammar");
  CHECK(w->json()["attempts"].size() == 3);
  CHECK(w->json()["attempts"][1]["error"].get<std::string>().find("exceeded") != std::string::npos);
  CHECK(f.chat().status()["brain_failures"] == 2);
}

TEST_CASE("a brain's out-of-bounds or undeclared action is refused, nothing moves; the chain does not retry it") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  Fixture f(rover_config(brains(primary, backup), chain_agent()));
  primary.always(ScriptedModelServer::answer(answer_with(waypoint(40, 0))));
  auto w = f.say("go forward 40 metres");
  CHECK(w->status() == 422);
  CHECK(w->json()["code"] == "ACTION_REJECTED");
  primary.always(ScriptedModelServer::answer(answer_with({{"method", "POST"}, {"path", "/api/cap/com.evil/fire"}})));
  w = f.say("fire");
  CHECK(w->status() == 404);
  CHECK(w->json()["brain"] == "primary");
  CHECK(backup.posts().empty());
  CHECK(f.dispatcher.requests.empty());
}

TEST_CASE("chat's deadline stays below runtime.handler_timeout_ms: a hung model still gets chat's own answer in time") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  primary.always(ScriptedModelServer::hang());
  auto config =
      rover_config(brains(primary, backup, {{"first_byte_timeout_ms", 60000}, {"timeout_ms", 60000}}), {{"provider", "primary"}});
  config["runtime"]["handler_timeout_ms"] = 1500;
  config["runtime"]["capabilities"]["chat"]["timeout_ms"] = 30000;
  Fixture f(config);
  CHECK(f.chat().settings().timeout == milliseconds(1000));  // 1500 - chat's 500 ms margin
  bool warned = false;
  for (const auto& line : f.host.log_lines())
    warned |= line.find("cold") != std::string::npos && line.find("runtime.handler_timeout_ms") != std::string::npos;
  CHECK(warned);
  const auto before = std::chrono::steady_clock::now();
  const auto w = f.say("go forward 1 metre");
  const auto took = std::chrono::steady_clock::now() - before;
  REQUIRE(w->status() == 200);
  CHECK(w->json()["brain"] == "grammar");
  CHECK(took < milliseconds(1200));
  CHECK(took >= milliseconds(900));
}

TEST_CASE("the API key stays out of chat's answers, thoughts, status and logs") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  primary.always(ScriptedModelServer::echo_key(401));
  ::setenv("RCAND_TEST_CHAIN_KEY", "sk-chain-secret-42", 1);
  Fixture f(rover_config(brains(primary, backup, {{"api_key_env", "RCAND_TEST_CHAIN_KEY"}}), {{"provider", "primary"}}));
  f.host.run_pending();
  const auto w = f.say("go forward 1 metre");
  REQUIRE(w->status() == 200);
  CHECK(primary.posts().at(0).authorization == "Bearer sk-chain-secret-42");
  const std::string everything = w->json().dump() +
                                 f.get("/api/thoughts/" + w->json()["thought_id"].get<std::string>(), Role::Owner).body.dump() +
                                 f.chat().status().dump();
  CHECK(everything.find("HTTP 401") != std::string::npos);
  CHECK(everything.find("sk-chain-secret") == std::string::npos);
  for (const auto& line : f.host.log_lines()) CHECK_MESSAGE(line.find("sk-chain-secret") == std::string::npos, line);
}

TEST_CASE("a model server that echoes the API key into any field: the key reaches no answer, thought, dispatch or log") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  const std::string key = "sk-echoed-secret-0123456789";
  ::setenv("RCAND_TEST_ECHO_KEY", key.c_str(), 1);
  Fixture f(rover_config(brains(primary, backup, {{"api_key_env", "RCAND_TEST_ECHO_KEY"}}), {{"provider", "primary"}}));
  f.host.run_pending();
  // Not understood: the key in the reply, the reasoning and every suggestion (what a USER is answered).
  primary.then(ScriptedModelServer::answer({{"reply", "your key is " + key},
                                            {"reasoning", key},
                                            {"action", nullptr},
                                            {"confidence", 0.2},
                                            {"suggestions", {"try " + key, key + " again", "x" + key + "y"}}}));
  // An action carrying the key in its body (and as an object key): dispatched to a declared custom capability.
  primary.then(ScriptedModelServer::answer(answer_with({{"method", "POST"},
                                                        {"path", "/api/cap/com.acme.gripper/grip"},
                                                        {"body", {{"state", "close"}, {"note", "key " + key}, {key, true}}}})));
  const auto refused = f.say("what is my key", Role::User);
  REQUIRE(refused->status() == 422);
  CHECK(refused->json()["suggestions"].size() == 3);
  CHECK(refused->json()["suggestions"][0] == "try [api key]");
  const auto dispatched = f.say("close it with the key", Role::User);
  REQUIRE(dispatched->status() == 200);
  REQUIRE(f.dispatcher.requests.size() == 1);
  CHECK(f.dispatcher.requests[0].body["note"] == "key [api key]");
  std::string everything = refused->json().dump() + dispatched->json().dump() + f.dispatcher.requests[0].body.dump();
  for (const auto& w : {refused, dispatched})
    everything += f.get("/api/thoughts/" + w->json()["thought_id"].get<std::string>(), Role::Owner).body.dump();
  INFO(everything);
  CHECK(everything.find(key) == std::string::npos);
  CHECK(everything.find("sk-echoed") == std::string::npos);  // no half key either
  for (const auto& line : f.host.log_lines()) CHECK_MESSAGE(line.find("sk-echoed") == std::string::npos, line);
}

TEST_CASE("a hostile model's texts are bounded: a 200 KB confidence, a 100 KB reply, huge suggestions") {
  ScriptedModelServer primary(ScriptedModelServer::Wire::OpenAI);
  ScriptedModelServer backup(ScriptedModelServer::Wire::Ollama);
  Fixture f(rover_config(brains(primary, backup), {{"provider", "primary"}}));
  f.host.run_pending();
  // The case: a string confidence of 200 KB was quoted whole in the answer, the thought and the log line.
  primary.then(
      ScriptedModelServer::answer({{"reply", "ok"}, {"action", waypoint(1, 0)}, {"confidence", std::string(200 * 1024, '9')}}));
  primary.then(ScriptedModelServer::answer({{"reply", std::string(100 * 1024, 'r')},
                                            {"reasoning", std::string(50 * 1024, 'w')},
                                            {"action", nullptr},
                                            {"confidence", 0.1},
                                            {"suggestions", {std::string(30 * 1024, 's'), std::string(30 * 1024, 't')}}}));
  const auto failed = f.say("go forward 1 metre");  // the model failed: the grammar brain answered
  REQUIRE(failed->status() == 200);
  CHECK(failed->json()["brain"] == "grammar");
  CHECK(failed->json()["attempts"][0]["error"].get<std::string>().find("confidence") != std::string::npos);
  const auto huge = f.say("do the thing");
  REQUIRE(huge->status() == 422);
  CHECK(huge->json()["raw_text"].get<std::string>().size() <= 4003);
  const auto huge_answer = huge->json();  // a copy to iterate: json() returns a temporary
  for (const auto& s : huge_answer["suggestions"]) CHECK(s.get<std::string>().size() <= 203);
  for (const auto& w : {failed, huge}) {
    const auto body = w->json().dump();
    CHECK_MESSAGE(body.size() < 16 * 1024, body.size());
    const auto thought = f.get("/api/thoughts/" + w->json()["thought_id"].get<std::string>(), Role::Owner).body.dump();
    CHECK_MESSAGE(thought.size() < 24 * 1024, thought.size());
  }
  for (const auto& line : f.host.log_lines()) CHECK_MESSAGE(line.size() < 8 * 1024, line.substr(0, 200));
}
