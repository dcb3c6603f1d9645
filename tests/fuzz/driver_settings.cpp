// libFuzzer target: a hardware driver's drivers[] entry (JSON, as the kernel hands it over after the YAML), through
// each driver's own settings reader, then through what those settings drive. The first byte picks the driver; the
// rest is the entry's JSON text, optionally followed by a NUL and bytes read as wheel commands.
//   pca9685   Pca9685Settings::from; accepted => address 0x03..0x77, prescale 3..255, 16 channels each used once,
//             timeouts in range; then every command through Motor::apply (what the drive writes): a bridge's two
//             inputs are never both on, a stopped bridge is all off, an ESC's pulse stays within min_us..max_us and
//             fits the PWM period (else its "neutral" would be a constant high, no stop signal at all).
//   gpio      GpioMotorSettings::from; accepted => no line and no PWM channel drives two things; then the real
//             GpioMotorDrive on a fake chip: start, the commands, halt. Replaying every line change: a bridge's IN1
//             and IN2 are never active together, and after halt every enable, PWM and input is off.
//   dynamixel DynamixelSettings::from (the entry, or [entry, robot config] for physics.kinematics); accepted =>
//             ids 0..252 used once, names used once, a baud rate the servos know and the one written, min < max,
//             a watchdog register value that fits.
// Refusals must be sdk::ConfigError with a message; anything else escaping is a crash.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "fuzz_check.hpp"
#include "plugins/dynamixel/settings.hpp"
#include "plugins/gpio_motor/gpio_motor_drive.hpp"
#include "plugins/gpio_motor/gpio_settings.hpp"
#include "plugins/gpio_motor/testing/fake_gpio.hpp"
#include "plugins/pca9685/motor_channels.hpp"
#include "plugins/pca9685/pca9685_drive.hpp"

namespace {

using nlohmann::json;
namespace pca = rcand::plugins::pca9685;
namespace gpio = rcand::plugins::gpio_motor;
namespace dxl = rcand::plugins::dynamixel;

// Wheel speeds from the command bytes: mostly in [-1, 1], with the edges a driver must clamp (NaN, +-inf, 2).
std::vector<double> speeds_of(std::string_view bytes) {
  std::vector<double> out;
  for (const unsigned char b : bytes) {
    switch (b) {
      case 0xFF: out.push_back(std::nan("")); break;
      case 0xFE: out.push_back(INFINITY); break;
      case 0xFD: out.push_back(-INFINITY); break;
      case 0xFC: out.push_back(2.0); break;
      default: out.push_back((static_cast<double>(b) - 126.0) / 126.0);
    }
    if (out.size() == 64) break;
  }
  return out;
}

bool off(const pca::ChannelCounts& c) { return c == pca::ChannelCounts::full_off(); }

void check_pca9685(const json& entry, const std::vector<double>& speeds) {
  const pca::Pca9685Settings s = pca::Pca9685Settings::from(rcand::sdk::ConfigView(entry));
  RCAND_FUZZ_CHECK(s.address >= 0x03 && s.address <= 0x77, "a 7-bit address outside the reserved ones");
  RCAND_FUZZ_CHECK(s.prescale >= pca::kMinPrescale && s.prescale <= pca::kMaxPrescale, "a prescale the chip takes");
  RCAND_FUZZ_CHECK(!s.bus_path.empty(), "a bus device");
  RCAND_FUZZ_CHECK(s.halt_deadline.count() >= 1 && s.command_timeout.count() >= 1 && s.i2c_timeout.count() >= 1,
                   "timeouts above 0");
  std::set<int> used;
  for (const pca::Motor* m : {&s.motors.left, &s.motors.right})
    for (const int ch : m->channels()) {
      RCAND_FUZZ_CHECK(ch >= 0 && ch < pca::kChannels, "a channel the board has");
      RCAND_FUZZ_CHECK(used.insert(ch).second, "a channel drives one thing");
    }
  const auto [first, last] = s.motors.span();
  RCAND_FUZZ_CHECK(pca::channel_block({}, first, last).size() == 1 + 4 * static_cast<std::size_t>(last - first + 1),
                   "one block covers the wheels' channels");
  const double period_us = 1e6 / pca::frequency_of(s.prescale, s.oscillator_hz);
  std::vector<double> commands = speeds;
  commands.push_back(0.0);  // every sequence ends stopped, as a halt leaves it
  for (const pca::Motor* m : {&s.motors.left, &s.motors.right}) {
    if (m->kind == pca::Motor::Kind::Esc)
      RCAND_FUZZ_CHECK(m->max_us < period_us, "an ESC's pulses (neutral: the stop) fit in the PWM period");
    pca::ChannelTable table;
    table.fill(pca::ChannelCounts::full_off());
    for (const double speed : commands) {
      m->apply(speed, table, s.prescale, s.oscillator_hz);
      const double clamped = std::isfinite(speed) ? std::clamp(speed, -1.0, 1.0) : 0.0;
      if (m->kind == pca::Motor::Kind::Esc) {
        const pca::ChannelCounts c = table[static_cast<std::size_t>(m->esc)];
        const double count_us = (s.prescale + 1) / s.oscillator_hz * 1e6;
        const double width_us = c.off * count_us;
        RCAND_FUZZ_CHECK(c.on == 0 && width_us >= m->min_us - count_us && width_us <= m->max_us + count_us,
                         "an ESC pulse within min_us..max_us");
        continue;
      }
      const auto& in1 = table[static_cast<std::size_t>(m->in1)];
      const auto& in2 = table[static_cast<std::size_t>(m->in2)];
      RCAND_FUZZ_CHECK(off(in1) || off(in2), "a bridge's two inputs are never both on");
      if (clamped == 0.0) {
        RCAND_FUZZ_CHECK(off(in1) && off(in2), "a stopped bridge has both inputs off");
        if (m->kind == pca::Motor::Kind::BridgeWithPwm)
          RCAND_FUZZ_CHECK(off(table[static_cast<std::size_t>(m->pwm)]), "a stopped bridge's pwm is off");
      }
    }
  }
}

// Every string line the settings name exists on the fake chip (a missing one is a start fault, tested elsewhere).
void name_lines(gpio::testing::FakeChip& chip, const gpio::GpioMotorSettings& s) {
  for (const gpio::MotorSettings* m : {&s.left, &s.right})
    for (const gpio::LineSettings* l : {&m->in1, &m->in2, m->enable ? &*m->enable : nullptr})
      if (l)
        if (const auto* name = std::get_if<std::string>(&l->line)) chip.add_name(*name);
}

void check_gpio(const json& entry, const std::vector<double>& speeds) {
  const gpio::GpioMotorSettings s = gpio::GpioMotorSettings::from(rcand::sdk::ConfigView(entry));
  if (s.left.pwm && s.right.pwm)
    RCAND_FUZZ_CHECK(s.left.pwm->chip != s.right.pwm->chip || s.left.pwm->channel != s.right.pwm->channel,
                     "one PWM channel drives one motor");
  auto log = std::make_shared<gpio::testing::EventLog>();
  auto chip = std::make_shared<gpio::testing::FakeChip>(log, 1024);
  name_lines(*chip, s);
  gpio::GpioMotorDrive drive(s, chip, [log](const gpio::PwmSettings& p) {
    return std::make_unique<gpio::testing::FakePwm>(log, "pwm" + std::to_string(p.chip) + "." + std::to_string(p.channel));
  });
  drive.start();  // the settings refuse a line named twice, so every request succeeds
  for (std::size_t i = 0; i + 1 < speeds.size(); i += 2) drive.set_wheel_speeds(speeds[i], speeds[i + 1]);
  drive.halt();

  std::map<std::string, bool> active;
  std::map<std::string, double> duty;
  for (const auto& event : log->events()) {
    active[event.line] = event.active;
    if (event.line.rfind("pwm", 0) == 0) duty[event.line] = event.duty;
    for (const gpio::MotorSettings* m : {&s.left, &s.right})
      RCAND_FUZZ_CHECK(!(active[gpio::describe(m->in1.line)] && active[gpio::describe(m->in2.line)]),
                       "a bridge's IN1 and IN2 are never active together");
  }
  for (const auto& [line, on] : active)
    RCAND_FUZZ_CHECK(line.rfind("pwm", 0) == 0 || !on, "after halt every enable and input is inactive");
  for (const auto& [pwm, value] : duty) RCAND_FUZZ_CHECK(value == 0.0, "after halt every PWM is at 0");
}

void check_dynamixel(const json& input) {
  const json& entry = input.is_array() && !input.empty() ? input[0] : input;
  const json robot = input.is_array() && input.size() > 1 ? input[1] : json::object();
  const dxl::DynamixelSettings s = dxl::DynamixelSettings::from(rcand::sdk::ConfigView(entry), rcand::sdk::ConfigView(robot));
  static const std::set<int> kBaudRates{9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000, 4500000};
  RCAND_FUZZ_CHECK(kBaudRates.count(s.baud_rate) == 1, "a baud rate the servos know");
  if (entry.contains("baud_rate") && !entry["baud_rate"].is_null())
    RCAND_FUZZ_CHECK(entry["baud_rate"].get<long long>() == s.baud_rate, "the baud rate is the one written");
  RCAND_FUZZ_CHECK(!s.port.empty() && !s.servos.empty(), "a port and servos");
  std::set<int> ids;
  std::set<std::string> names;
  for (const auto& servo : s.servos) {
    RCAND_FUZZ_CHECK(servo.id <= 252, "a servo id, not broadcast or reserved");
    RCAND_FUZZ_CHECK(ids.insert(servo.id).second && names.insert(servo.name).second, "ids and names used once");
    if (servo.min_deg && servo.max_deg) RCAND_FUZZ_CHECK(*servo.min_deg < *servo.max_deg, "min_deg below max_deg");
  }
  RCAND_FUZZ_CHECK(s.watchdog.count() >= 0 && s.watchdog_units() <= 127, "the watchdog fits its register");
  RCAND_FUZZ_CHECK(s.poll_hz >= 1 && s.poll_hz <= 500, "a poll rate in range");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::size_t nul = rest.find('\0');
  const json entry = json::parse(rest.substr(0, nul), nullptr, false);
  // The kernel hands a plugin one drivers[] item, a mapping (with id and protocol), and the robot's config, a mapping.
  const bool wellformed = entry.is_object() || (data[0] % 3 == 2 && entry.is_array() && !entry.empty() && entry[0].is_object() &&
                                                (entry.size() == 1 || entry[1].is_object()));
  if (!wellformed) return 0;
  const auto speeds = speeds_of(nul == std::string_view::npos ? std::string_view{} : rest.substr(nul + 1));
  try {
    switch (data[0] % 3) {
      case 0: check_pca9685(entry, speeds); break;
      case 1: check_gpio(entry, speeds); break;
      default: check_dynamixel(entry);
    }
  } catch (const rcand::sdk::ConfigError& error) {
    RCAND_FUZZ_CHECK(std::strlen(error.what()) > 0, "a refusal explains itself");
  }
  return 0;
}
