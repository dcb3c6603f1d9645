// The grammar brain: the phrase set (phrases.tsv, >= 95 % exact, misses printed), and the rules around it.
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "grammar_brain.hpp"
#include "words.hpp"

using nlohmann::json;
using rcand::plugins::chat::GrammarBrain;
using rcand::plugins::chat::tokenize;

namespace {

// The simulated rover as chat describes it to a brain.
rcand::sdk::BrainContext rover() {
  rcand::sdk::BrainContext c;
  c.capabilities = {"status", "teleop", "nav", "vision", "chat", "com.acme.gripper"};
  const json close{{"method", "POST"}, {"path", "/api/cap/com.acme.gripper/grip"}, {"body", {{"state", "close"}}}};
  const json open{{"method", "POST"}, {"path", "/api/cap/com.acme.gripper/grip"}, {"body", {{"state", "open"}}}};
  for (const char* say : {"close the gripper", "grip", "grab it"}) c.phrases.push_back({say, close});
  for (const char* say : {"open the gripper", "release", "let go"}) c.phrases.push_back({say, open});
  c.limits = {{"max_linear_speed", 1.0},
              {"physics", {{"wheel_circumference_m", 0.21}, {"turn_time_per_deg_s", 0.008}, {"max_wheel_rps", 1.0}}}};
  c.pose = rcand::sdk::Pose2d{0.0, 0.0, 0.0};
  return c;
}

// The shorthand of phrases.tsv as the action it stands for (null for "none").
json expand(const std::string& expected) {
  std::istringstream in(expected);
  std::string kind;
  in >> kind;
  auto number = [&] {
    double v = 0;
    in >> v;
    return v;
  };
  if (kind == "none") return nullptr;
  if (kind == "stop") return {{"method", "POST"}, {"path", "/api/stop"}, {"body", {{"reason", "chat"}}}};
  if (kind == "status") return {{"method", "GET"}, {"path", "/api/status"}};
  if (kind == "close" || kind == "open")
    return {{"method", "POST"}, {"path", "/api/cap/com.acme.gripper/grip"}, {"body", {{"state", kind}}}};
  if (kind == "wp") {
    const double d = number(), h = number(), s = number();
    return {{"method", "POST"}, {"path", "/api/nav/waypoint"}, {"body", {{"distance_m", d}, {"heading_deg", h}, {"speed", s}}}};
  }
  if (kind == "move") {
    const double l = number(), a = number(), ms = number();
    return {{"method", "POST"},
            {"path", "/api/action"},
            {"body", {{"type", "move"}, {"linear", l}, {"angular", a}, {"duration_ms", static_cast<long long>(ms)}}}};
  }
  std::string path, body;
  in >> path;
  std::getline(in, body);
  if (kind == "get") return {{"method", "GET"}, {"path", path}};
  if (kind == "post") return {{"method", "POST"}, {"path", path}, {"body", json::parse(body)}};
  FAIL("phrases.tsv: unknown shorthand '" << kind << "'");
  return nullptr;
}

// Equal, numbers to within 1e-3 (the file writes them rounded).
bool same(const json& a, const json& b) {
  if (a.is_number() && b.is_number()) return std::abs(a.get<double>() - b.get<double>()) <= 1e-3;
  if (a.type() != b.type() || a.size() != b.size()) return false;
  if (a.is_object()) {
    for (auto it = a.begin(); it != a.end(); ++it)
      if (!b.contains(it.key()) || !same(it.value(), b[it.key()])) return false;
    return true;
  }
  if (a.is_array()) {
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!same(a[i], b[i])) return false;
    return true;
  }
  return a == b;
}

}  // namespace

TEST_CASE("the phrase set: at least 200 phrases, at least 95 % read exactly") {
  std::ifstream file(RCAND_SOURCE_DIR "/plugins/chat/phrases.tsv");
  REQUIRE(file.good());
  const auto context = rover();
  std::string line;
  std::size_t total = 0, exact = 0, negatives = 0;
  std::ostringstream misses;
  while (std::getline(file, line)) {
    if (line.empty() || line.front() == '#') continue;
    const auto tab = line.find('\t');
    REQUIRE_MESSAGE(tab != std::string::npos, "phrases.tsv: no tab in: " << line);
    const std::string instruction = line.substr(0, tab);
    const json expected = expand(line.substr(tab + 1));
    negatives += expected.is_null();
    const auto p = GrammarBrain::understand(instruction, context);
    ++total;
    const bool ok = expected.is_null() ? p.action.is_null() && !p.suggestions.empty() : same(p.action, expected);
    if (ok) ++exact;
    else
      misses << "  '" << instruction << "': expected " << expected.dump() << ", got " << p.action.dump() << " (" << p.raw_text
             << ")\n";
  }
  const double accuracy = 100.0 * static_cast<double>(exact) / static_cast<double>(total);
  MESSAGE("phrase set: " << exact << "/" << total << " exact (" << accuracy << " %), " << negatives << " negatives");
  if (exact != total) MESSAGE("misses:\n" << misses.str());
  CHECK(total >= 200);
  CHECK(negatives >= 30);
  CHECK(accuracy >= 95.0);
}

TEST_CASE("confidence is 1 for an exact reading, lower for a corrected word, 0 when not understood") {
  const auto context = rover();
  CHECK(GrammarBrain::understand("go forward 1 metre", context).confidence == 1.0);
  const auto fuzzy = GrammarBrain::understand("go foward 1 metre", context);
  REQUIRE(fuzzy.confidence);
  CHECK(*fuzzy.confidence < 1.0);
  CHECK(*fuzzy.confidence >= 0.5);
  CHECK(fuzzy.raw_text.find("foward->forward") != std::string::npos);
  const auto no = GrammarBrain::understand("dance", context);
  CHECK(no.action.is_null());
  CHECK(no.confidence == 0.0);
  CHECK(no.brain == "grammar");
  CHECK(no.model == "grammar-en-1");
}

TEST_CASE("not understood answers with the closest known commands") {
  const auto context = rover();
  auto p = GrammarBrain::understand("go forward 2", context);
  CHECK(p.action.is_null());
  CHECK(p.raw_text.find("unit") != std::string::npos);
  REQUIRE(!p.suggestions.empty());
  CHECK(p.suggestions.front().find("forward") != std::string::npos);
  p = GrammarBrain::understand("close the claw", context);
  CHECK(std::find(p.suggestions.begin(), p.suggestions.end(), "close the gripper") != p.suggestions.end());
  p = GrammarBrain::understand("vorwärts", context);
  CHECK(p.raw_text.find("English") != std::string::npos);
  CHECK(p.suggestions.size() == 3);
}

TEST_CASE("a capability the robot does not declare is never proposed") {
  auto context = rover();
  context.capabilities = {"status", "chat"};
  for (const char* text : {"go forward 1 metre", "spin left", "what do you see", "where are you", "cancel navigation"})
    CHECK_MESSAGE(GrammarBrain::understand(text, context).action.is_null(), text);
  CHECK(GrammarBrain::understand("stop", context).action["path"] == "/api/stop");
  CHECK(GrammarBrain::understand("status", context).action["path"] == "/api/status");
}

TEST_CASE("without nav, a drive or a turn is a teleop move timed from the physics block") {
  auto context = rover();
  context.capabilities = {"status", "teleop"};
  // 1 m at speed 0.5 on 0.21 m wheels at 1 rps: 1 / 0.105 s.
  auto p = GrammarBrain::understand("go forward 1 metre", context);
  CHECK(p.action["path"] == "/api/action");
  CHECK(p.action["body"]["linear"] == 0.5);
  CHECK(p.action["body"]["duration_ms"] == 9524);
  // 90 degrees at 0.008 s/deg and speed 0.5: 1.44 s, counter-clockwise.
  p = GrammarBrain::understand("turn left 90 degrees", context);
  CHECK(p.action["body"]["angular"] == 0.5);
  CHECK(p.action["body"]["duration_ms"] == 1440);
  // A turn and a drive need nav.
  CHECK(GrammarBrain::understand("turn left and go forward 1 metre", context).action.is_null());
}

TEST_CASE("go to needs a pose; without one it says so") {
  auto context = rover();
  context.pose.reset();
  const auto p = GrammarBrain::understand("go to x 1 y 2", context);
  CHECK(p.action.is_null());
  CHECK(p.raw_text.find("where the robot is") != std::string::npos);
  context.pose = rcand::sdk::Pose2d{1.0, 1.0, 90.0};  // facing +y: the point (1, 0) is behind, to the right
  const auto q = GrammarBrain::understand("go to x 1 y 0", context);
  CHECK(q.action["body"]["distance_m"] == 1.0);
  CHECK(q.action["body"]["heading_deg"] == -180.0);
}

TEST_CASE("tokens: case, punctuation, units glued to numbers, signs and symbols") {
  CHECK(*tokenize("Turn LEFT 90°, now!") == std::vector<std::string>{"turn", "left", "90", "degrees", "now"});
  CHECK(*tokenize("x=-1.5,y=2") == std::vector<std::string>{"x", "-1.5", "y", "2"});
  CHECK(*tokenize("1.5m at 30%") == std::vector<std::string>{"1.5", "m", "at", "30", "percent"});
  CHECK(*tokenize("what's the e-stop") == std::vector<std::string>{"whats", "the", "estop"});
  CHECK_FALSE(tokenize("вперёд").has_value());
}

TEST_CASE("the grammar brain answers fast") {
  const auto context = rover();
  const auto started = std::chrono::steady_clock::now();
  for (int i = 0; i < 200; ++i) (void)GrammarBrain::understand("turn right 30 degrees and drive 50 cm slowly", context);
  const auto each = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count() / 200;
  MESSAGE("grammar brain: " << each << " ms per instruction");
  CHECK(each < 5.0);  // generous for sanitizer builds; typically well under 1 ms
}
