// The H-bridge rules, checked at every single line change the fake chip records: the two inputs are never active
// together, and an input only changes while the enable is off and the PWM at 0. Exact sequences first, then random
// command sequences (the property), also with lines the kernel refuses and with halts from another thread.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <thread>

#include "hbridge.hpp"
#include "testing/fake_gpio.hpp"

using namespace rcand::plugins::gpio_motor;
using testing::Event;
using testing::EventLog;
using testing::FakeChip;
using testing::FakePwm;

namespace {

struct Wiring {
  bool enable = true;
  bool pwm = true;
  bool active_low_enable = false;
};

struct Names {
  std::string in1, in2, en, pwm;
};

std::unique_ptr<HBridge> bridge(FakeChip& chip, const std::shared_ptr<EventLog>& log, Wiring w, unsigned base, Names& names) {
  names = {"line " + std::to_string(base), "line " + std::to_string(base + 1), w.enable ? "line " + std::to_string(base + 2) : "",
           w.pwm ? "pwm" + std::to_string(base) : ""};
  auto en = w.enable ? chip.request_output(base + 2, w.active_low_enable, "t") : nullptr;
  auto in1 = chip.request_output(base, false, "t");
  auto in2 = chip.request_output(base + 1, false, "t");
  auto pwm = w.pwm ? std::make_unique<FakePwm>(log, names.pwm) : nullptr;
  return std::make_unique<HBridge>("m" + std::to_string(base), std::move(in1), std::move(in2), std::move(en), std::move(pwm));
}

// Replays the log for one bridge; returns the first violated rule, or "" when every step was safe.
std::string violations(const std::vector<Event>& events, const Names& n) {
  std::map<std::string, bool> active;
  double duty = 0.0;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    const bool input = e.line == n.in1 || e.line == n.in2;
    if (e.line == n.pwm) duty = e.duty;
    else if (input || e.line == n.en) {
      if (input && !e.request && active[e.line] != e.active) {
        if (!n.en.empty() && active[n.en]) return "step " + std::to_string(i) + ": " + e.line + " changed with the enable on";
        if (!n.pwm.empty() && duty > 0) return "step " + std::to_string(i) + ": " + e.line + " changed with the PWM on";
      }
      active[e.line] = e.active;
    }
    if (active[n.in1] && active[n.in2]) return "step " + std::to_string(i) + ": shoot-through, both inputs active";
  }
  return "";
}

std::vector<std::string> lines_of(const std::vector<Event>& events) {
  std::vector<std::string> out;
  for (const auto& e : events)
    out.push_back(e.line + (e.duty > 0 ? "=" + std::to_string(static_cast<int>(e.duty * 100)) + "%" : e.active ? "=1" : "=0"));
  return out;
}

double random_speed(std::mt19937& rng) {
  switch (rng() % 8) {
    case 0: return 0.0;
    case 1: return std::numeric_limits<double>::quiet_NaN();
    case 2: return (rng() % 2 ? 1 : -1) * std::numeric_limits<double>::infinity();
    case 3: return (rng() % 2 ? 1e-9 : -1e-9);
    default: return std::uniform_real_distribution<double>(-1.5, 1.5)(rng);
  }
}

}  // namespace

TEST_CASE("hbridge: forward, a direction change, stop: the exact order of line changes") {
  auto log = std::make_shared<EventLog>();
  FakeChip chip(log);
  Names n;
  auto b = bridge(chip, log, {}, 0, n);
  log->clear();
  REQUIRE(b->set(0.5));
  CHECK(lines_of(log->events()) ==
        std::vector<std::string>{"line 2=0", "pwm0=0", "line 1=0", "line 0=1", "pwm0=50%", "line 2=1"});
  log->clear();
  REQUIRE(b->set(0.8));  // same direction: the duty only
  CHECK(lines_of(log->events()) == std::vector<std::string>{"pwm0=80%"});
  log->clear();
  REQUIRE(b->set(-0.3));  // power off, release IN1, then IN2, then power
  CHECK(lines_of(log->events()) ==
        std::vector<std::string>{"line 2=0", "pwm0=0", "line 0=0", "line 1=1", "pwm0=30%", "line 2=1"});
  log->clear();
  REQUIRE(b->set(0.0));
  CHECK(lines_of(log->events()) == std::vector<std::string>{"line 2=0", "pwm0=0", "line 0=0", "line 1=0"});
  CHECK(b->direction() == HBridge::Direction::None);
}

TEST_CASE("hbridge: active-low enable is inactive (high) from its request on") {
  auto log = std::make_shared<EventLog>();
  FakeChip chip(log);
  Names n;
  auto b = bridge(chip, log, {true, false, true}, 0, n);
  const auto requested = log->events();
  REQUIRE(requested.size() == 3);
  CHECK(requested[0].line == "line 2");
  CHECK(requested[0].request);
  CHECK(requested[0].physical);  // high = disabled, at the request: no glitch
  CHECK_FALSE(requested[0].active);
  b->set(1.0);
  CHECK_FALSE(log->events().back().physical);  // enabled = driven low
  CHECK(log->events().back().active);
}

TEST_CASE("hbridge: without PWM, speed is on/off at the threshold; NaN and infinities stop it") {
  auto log = std::make_shared<EventLog>();
  FakeChip chip(log);
  Names n;
  auto b = bridge(chip, log, {true, false, false}, 0, n);
  b->set(0.01);
  CHECK(b->direction() == HBridge::Direction::None);
  b->set(0.2);
  CHECK(b->direction() == HBridge::Direction::Forward);
  CHECK(b->duty() == 1.0);
  b->set(std::numeric_limits<double>::quiet_NaN());
  CHECK(b->direction() == HBridge::Direction::None);
  b->set(-0.7);
  CHECK(b->direction() == HBridge::Direction::Reverse);
  b->set(-std::numeric_limits<double>::infinity());  // not a speed: stop rather than guess full reverse
  CHECK(b->direction() == HBridge::Direction::None);
  CHECK(violations(log->events(), n).empty());
}

TEST_CASE("property: random command sequences never put both inputs active or change direction under power") {
  for (const Wiring wiring :
       {Wiring{true, true, false}, Wiring{true, false, true}, Wiring{false, true, false}, Wiring{false, false, false}}) {
    for (unsigned seed = 1; seed <= 20; ++seed) {
      auto log = std::make_shared<EventLog>();
      FakeChip chip(log);
      Names n;
      auto b = bridge(chip, log, wiring, 0, n);
      std::mt19937 rng(seed);
      for (int step = 0; step < 500; ++step) {
        if (rng() % 10 == 0) b->stop();
        else b->set(random_speed(rng));
      }
      CAPTURE(seed);
      CAPTURE(wiring.enable);
      CAPTURE(wiring.pwm);
      CHECK(violations(log->events(), n) == "");
    }
  }
}

TEST_CASE("property: a line the kernel refuses never leaves both inputs active") {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    auto log = std::make_shared<EventLog>();
    FakeChip chip(log);
    Names n;
    auto b = bridge(chip, log, {true, true, false}, 0, n);
    std::mt19937 rng(seed);
    for (int step = 0; step < 200; ++step) {
      if (step == 100) chip.refuse(rng() % 2 ? "line 0" : "line 1");  // an input stuck where it is
      b->set(random_speed(rng));
    }
    CAPTURE(seed);
    CHECK(violations(log->events(), n) == "");
  }
}

TEST_CASE("the checker itself catches shoot-through and a direction change under power") {
  const Names n{"a", "b", "en", "p"};
  CHECK(violations({{"a", false, true, true, 0}, {"b", false, true, true, 0}}, n).find("shoot-through") != std::string::npos);
  CHECK(violations({{"en", false, true, true, 0}, {"a", false, true, true, 0}}, n).find("changed with the enable on") !=
        std::string::npos);
  CHECK(violations({{"p", false, true, true, 0.5}, {"b", false, true, true, 0}}, n).find("changed with the PWM on") !=
        std::string::npos);
}
