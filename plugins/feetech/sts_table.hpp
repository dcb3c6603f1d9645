// The STS/SMS control table and the models rcand knows. Addresses from LeRobot's src/lerobot/motors/feetech/tables.py
// (STS_SMS_SERIES_CONTROL_TABLE, MODEL_NUMBER_TABLE, MODEL_RESOLUTION) and Feetech's SCServo SDK for Linux (SMS_STS.h,
// the SMS_STS_* addresses; it has no torque limit entry, lerobot has 48), which agree; two-byte values little-endian
// (protocol 0; SCSerial.h End = 0). SCS servos (protocol 1: big-endian,
// 10-bit positions, torque limit elsewhere) have another table and are not driven by this plugin.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace rcand::plugins::feetech {

namespace sts {
inline constexpr std::uint8_t kModelNumber = 3;  // 2 bytes, read-only
inline constexpr std::uint8_t kId = 5;
inline constexpr std::uint8_t kBaudRate = 6;
inline constexpr std::uint8_t kMinAngleLimit = 9;   // 2 bytes, ticks
inline constexpr std::uint8_t kMaxAngleLimit = 11;  // 2 bytes, ticks
inline constexpr std::uint8_t kOperatingMode = 33;  // EEPROM: 0 position, 1 wheel (constant speed), 2 PWM, 3 step
inline constexpr std::uint8_t kTorqueEnable = 40;   // 0 off, 1 on (128 would recalibrate the centre: never sent)
inline constexpr std::uint8_t kAcceleration = 41;   // 100 steps/s^2 units, 0 = the servo's maximum
inline constexpr std::uint8_t kGoalPosition = 42;   // 2 bytes, sign bit 15
inline constexpr std::uint8_t kGoalTime = 44;       // 2 bytes, ms; 0 = move at the goal speed
inline constexpr std::uint8_t kGoalSpeed =
    46;  // 2 bytes, steps/s, sign bit 15 (wheel mode); in position mode a limit, 0 = maximum
inline constexpr std::uint8_t kTorqueLimit = 48;         // 2 bytes, 0.1 % of the stall torque (0..1000)
inline constexpr std::uint8_t kLock = 55;                // 1: EEPROM writes locked, 0: open
inline constexpr std::uint8_t kPresentPosition = 56;     // 2 bytes, sign bit 15
inline constexpr std::uint8_t kPresentSpeed = 58;        // 2 bytes, sign bit 15
inline constexpr std::uint8_t kPresentLoad = 60;         // 2 bytes, sign bit 10, 0.1 %
inline constexpr std::uint8_t kPresentVoltage = 62;      // 0.1 V
inline constexpr std::uint8_t kPresentTemperature = 63;  // deg C
inline constexpr std::uint8_t kMoving = 66;
inline constexpr std::uint8_t kPresentCurrent = 69;  // 2 bytes

// The command block every command and halt writes in one sync write: goal position, goal time, goal speed, torque
// limit (42..49).
inline constexpr std::uint8_t kCommandBlock = kGoalPosition;
inline constexpr std::uint8_t kCommandBlockLength = 8;
// The status block one sync read per poll fetches: present position .. temperature (56..63).
inline constexpr std::uint8_t kStatusBlock = kPresentPosition;
inline constexpr std::uint8_t kStatusBlockLength = 8;

inline constexpr std::uint8_t kModePosition = 0;
inline constexpr std::uint8_t kModeWheel = 1;
inline constexpr int kSignBit = 15;
inline constexpr int kLoadSignBit = 10;
}  // namespace sts

struct Model {
  std::string_view name;  // "sts3215"
  std::uint16_t number;   // as read at address 3
  int ticks_per_rev;      // over 360 degrees
  double max_speed;       // steps/s at the rated voltage (its no-load speed), the wheel speed at 1.0 by default
};

// STS3215 (the SO-ARM100/101's servo, model 777) and STS3250 (2825), from lerobot's MODEL_NUMBER_TABLE.
std::optional<Model> find_model(std::uint16_t number);
std::optional<Model> find_model(std::string_view name);  // case-insensitive: "STS3215" as the SO-ARM presets write it

}  // namespace rcand::plugins::feetech
