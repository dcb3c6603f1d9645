// The gpio drive on the fake chip (settings, line requests, commands, halt, named faults, halts racing commands),
// the real libgpiod backend's named faults on a machine without the chip, and the sysfs PWM on a fake sysfs tree.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "gpio_motor_drive.hpp"
#include "libgpiod_chip.hpp"
#include "sysfs_pwm.hpp"
#include "testing/fake_gpio.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace rcand::plugins::gpio_motor;
using nlohmann::json;
using testing::EventLog;
using testing::FakeChip;
using testing::FakePwm;

namespace {

json config() {
  return json::parse(R"({"channels": {
      "left":  {"in1": 17, "in2": 27, "enable": 22, "pwm": {"chip": 0, "channel": 0}},
      "right": {"in1": "GPIO23", "in2": "GPIO24", "enable": {"line": 25, "active_low": true}, "reverse": true}}})");
}

struct Rig {
  std::shared_ptr<EventLog> log = std::make_shared<EventLog>();
  std::shared_ptr<FakeChip> chip = std::make_shared<FakeChip>(log);
  std::unique_ptr<GpioMotorDrive> drive;
  explicit Rig(json c = config()) {
    chip->add_name("GPIO23");
    chip->add_name("GPIO24");
    drive = std::make_unique<GpioMotorDrive>(
        GpioMotorSettings::from(rcand::sdk::ConfigView(std::move(c))), chip, [log = log](const PwmSettings& p) {
          return std::make_unique<FakePwm>(log, "pwm" + std::to_string(p.chip) + "." + std::to_string(p.channel));
        });
  }
  // The level of every line (logical) after the log so far.
  std::map<std::string, bool> levels() const {
    std::map<std::string, bool> out;
    for (const auto& e : log->events()) out[e.line] = e.active;
    return out;
  }
};

std::string error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("settings: lines by offset or name, active-low, PWM; errors name the key") {
  const auto s = GpioMotorSettings::from(rcand::sdk::ConfigView(config()));
  CHECK(std::get<unsigned>(s.left.in1.line) == 17);
  CHECK(std::get<std::string>(s.right.in1.line) == "GPIO23");
  CHECK(s.right.enable->active_low);
  CHECK(s.left.pwm->frequency_hz == 1000.0);
  CHECK(s.first_line_name() == "GPIO23");
  auto bad = [](const std::function<void(json&)>& edit) {
    json c = config();
    edit(c);
    return error_of([&] { GpioMotorSettings::from(rcand::sdk::ConfigView(c)); });
  };
  CHECK(bad([](json& c) { c["channels"].erase("right"); }).find("channels.right: required") == 0);
  CHECK(bad([](json& c) { c["channels"]["left"].erase("in2"); }).find("channels.left.in2: required") == 0);
  CHECK(bad([](json& c) { c["channels"]["left"]["in1"] = -3; }).find("channels.left.in1: expected a line offset") == 0);
  CHECK(bad([](json& c) { c["channels"]["right"]["in2"] = 17; }) == "channels.right.in2: line 17 is used twice");
  CHECK(bad([](json& c) { c["channels"]["left"]["pwm"]["frequency_hz"] = 0; }).find("channels.left.pwm.frequency_hz") == 0);
  CHECK(bad([](json& c) { c["chip"] = true; }).find("chip: expected a chip label") == 0);
  // One PWM channel for both motors (found by fuzzing): a command to one would set the other's speed.
  CHECK(bad([](json& c) {
          c["channels"]["right"]["pwm"] = {{"chip", 0}, {"channel", 0}};
        }) == "channels.right.pwm: pwmchip0 channel 0 is used twice: each motor needs its own PWM channel");
  CHECK_NOTHROW(GpioMotorSettings::from(rcand::sdk::ConfigView([] {
    json c = config();
    c["channels"]["right"]["pwm"] = {{"chip", 0}, {"channel", 1}};
    return c;
  }())));
}

TEST_CASE("start: every line requested inactive, the enable first; the active-low enable high from its request") {
  Rig rig;
  rig.drive->start();
  const auto events = rig.log->events();
  REQUIRE(events.size() >= 6);
  CHECK(events[0].line == "line 22");  // the enable before the inputs
  CHECK(events[0].request);
  CHECK_FALSE(events[0].physical);
  CHECK(events[3].line == "line 25");
  CHECK(events[3].request);
  CHECK(events[3].physical);  // active-low: inactive is high, from the first instant
  for (const auto& e : events) CHECK_FALSE(e.active);
  CHECK(rig.drive->status()["fail_safe"].get<std::string>().find("pull-down on each enable input") != std::string::npos);
}

TEST_CASE("wheel speeds: PWM duty on the left, on/off on the right, the mirrored motor reversed; halt powers off first") {
  Rig rig;
  rig.drive->start();
  rig.drive->set_wheel_speeds(0.4, 0.6);
  auto levels = rig.levels();
  CHECK(levels["line 17"]);
  CHECK_FALSE(levels["line 27"]);
  CHECK(rig.log->events().back().line == "line 25");  // power last
  CHECK(levels["line 25"]);
  CHECK_FALSE(levels["line \"GPIO23\""]);  // reversed: positive speed drives IN2
  CHECK(levels["line \"GPIO24\""]);
  CHECK(rig.drive->status()["motors"]["left"]["duty"] == 0.4);

  rig.log->clear();
  rig.drive->halt();
  const auto events = rig.log->events();
  REQUIRE(events.size() >= 4);
  // Both bridges lose power before any input changes.
  CHECK(events[0].line == "line 22");
  CHECK(events[1].line == "pwm0.0");
  CHECK(events[2].line == "line 25");
  levels = rig.levels();
  for (const char* line : {"line 17", "line 27", "line 22", "line 25", "line \"GPIO23\"", "line \"GPIO24\""})
    CHECK_FALSE(levels[line]);
  CHECK(rig.drive->status()["halts"] == 1);
}

TEST_CASE("named faults: a missing line, a busy line, a line the kernel refuses") {
  {
    Rig rig(json::parse(R"({"channels": {"left": {"in1": 17, "in2": 99}, "right": {"in1": 5, "in2": 6}}})"));
    CHECK(error_of([&] { rig.drive->start(); }) == "gpiochip0 [fake] has no line 99");
  }
  {
    Rig rig;
    rig.chip->hold("line 27");
    CHECK(error_of([&] { rig.drive->start(); }) == "cannot request line 27 of gpiochip0 [fake] as an output: busy");
  }
  Rig rig;
  rig.drive->start();
  rig.chip->refuse("line \"GPIO24\"");
  CHECK(error_of([&] { rig.drive->set_wheel_speeds(0.5, 0.5); }) ==
        "gpio drive: the kernel refused a line change on the right bridge; both motors stopped");
  const auto levels = rig.levels();
  CHECK_FALSE(levels.at("line 22"));
  CHECK_FALSE(levels.at("line 17"));
  CHECK_THROWS_AS(
      GpioMotorDrive(GpioMotorSettings::from(rcand::sdk::ConfigView(config())), rig.chip, nullptr).set_wheel_speeds(0, 0),
      GpioError);  // not started
}

TEST_CASE("property: halts racing random commands from another thread never cause shoot-through") {
  Rig rig;
  rig.drive->start();
  std::thread halter([&] {
    for (int i = 0; i < 300; ++i) rig.drive->halt();
  });
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> speed(-1.0, 1.0);
  for (int i = 0; i < 1000; ++i) rig.drive->set_wheel_speeds(speed(rng), speed(rng));
  halter.join();
  std::map<std::string, bool> active;
  for (const auto& e : rig.log->events()) {
    active[e.line] = e.active;
    REQUIRE_FALSE((active["line 17"] && active["line 27"]));
    REQUIRE_FALSE((active["line \"GPIO23\""] && active["line \"GPIO24\""]));
  }
}

TEST_CASE("libgpiod backend: a chip or a line name that is not there is a named fault") {
  CHECK_THROWS_WITH_AS(LibgpiodChip::open(std::string("rcand-no-such-chip"), std::nullopt),
                       doctest::Contains("no GPIO chip 'rcand-no-such-chip' (tried it as a label, a name, a path and a number)"),
                       GpioError);
  CHECK_THROWS_WITH_AS(LibgpiodChip::open(std::nullopt, std::string("RCAND_NO_SUCH_LINE")),
                       "no GPIO chip has a line named \"RCAND_NO_SUCH_LINE\"; gpioinfo lists the line names, or set chip",
                       GpioError);
  if (!std::filesystem::exists("/dev/gpiochip0"))
    CHECK_THROWS_WITH_AS(LibgpiodChip::open(std::nullopt, std::nullopt), doctest::Contains("no GPIO chip labelled pinctrl-rp1"),
                         GpioError);
}

TEST_CASE("plugin: loads against its manifest; a missing chip fails the instance by name") {
  rcand::sdk::testing::FakeHost host;
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/gpio.json");
  host.load(RCAND_ENTRY_FUNCTION, json::parse(in));
  json c = config();
  c["chip"] = "rcand-no-such-chip";
  CHECK_THROWS_WITH_AS(host.add_driver("base", "gpio", c), doctest::Contains("no GPIO chip 'rcand-no-such-chip'"),
                       rcand::sdk::testing::HostError);
  CHECK(host.motion().actuators().empty());
}

TEST_CASE("sysfs PWM: period from the frequency, duty in nanoseconds, disabled when released") {
  const auto root = std::filesystem::temp_directory_path() / ("rcand-pwm-" + std::to_string(::getpid()));
  const auto dir = root / "class/pwm/pwmchip0/pwm1";
  std::filesystem::create_directories(dir);
  for (const char* file : {"period", "duty_cycle", "enable", "../export"}) std::ofstream(dir / file) << "";
  const auto read = [&](const char* file) {
    std::ifstream in(dir / file);
    std::string text;
    in >> text;
    return text;
  };
  {
    SysfsPwm pwm(0, 1, 1000.0, root.string());
    CHECK(read("period") == "1000000");
    CHECK(read("enable") == "1");
    CHECK(pwm.set_duty(0.5));
    CHECK(read("duty_cycle") == "500000");
  }
  CHECK(read("enable") == "0");
  CHECK_THROWS_WITH_AS(SysfsPwm(3, 0, 1000.0, root.string()), doctest::Contains("enable the PWM overlay"), GpioError);
  std::filesystem::remove_all(root);
}

TEST_CASE("standby (a TB6612's STBY shared by both motors): requested first, active only while a motor runs") {
  json c = config();
  c["standby"] = 19;
  Rig rig(c);
  rig.drive->start();
  auto events = rig.log->events();
  REQUIRE_FALSE(events.empty());
  CHECK(events[0].line == "line 19");  // both bridges stay off while their lines are set up
  CHECK(events[0].request);
  CHECK_FALSE(rig.levels()["line 19"]);
  rig.drive->set_wheel_speeds(0.5, 0.5);
  CHECK(rig.log->events().back().line == "line 19");  // on once both bridges have their inputs
  CHECK(rig.levels()["line 19"]);
  rig.drive->set_wheel_speeds(0.0, 0.0);
  CHECK_FALSE(rig.levels()["line 19"]);
  rig.drive->set_wheel_speeds(-0.3, 0.0);
  CHECK(rig.levels()["line 19"]);
  rig.log->clear();
  rig.drive->halt();
  events = rig.log->events();
  REQUIRE_FALSE(events.empty());
  CHECK(events[0].line == "line 19");  // off before anything else
  CHECK_FALSE(rig.levels()["line 19"]);
  CHECK(rig.drive->status()["fail_safe"].get<std::string>().find("shared standby line") != std::string::npos);
  // A standby line the kernel refuses stops both motors and says which line it was.
  json refused = config();
  refused["standby"] = 19;
  Rig faulty(refused);
  faulty.chip->refuse("line 19");
  faulty.drive->start();
  CHECK(error_of([&] { faulty.drive->set_wheel_speeds(0.5, 0.5); }).find("standby line; both motors stopped") !=
        std::string::npos);
  // One line drives one thing: the standby line is no motor's line too.
  json twice = config();
  twice["standby"] = 22;
  CHECK(error_of([&] { GpioMotorSettings::from(rcand::sdk::ConfigView(twice)); }) ==
        "channels.left.enable: line 22 is used twice");
}
