// What rcand knows of each Dynamixel model: its control table (the addresses differ between the X/MX(2.0) family and
// the P family) and its units. Position resolution is per model: an X-series servo has 4096 ticks a turn centred
// on 2048, a PH54-200 1,003,846 centred on 0; converting degrees with the wrong one moves a joint to the wrong place.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace rcand::plugins::dynamixel {

// Control-table addresses of the registers rcand uses. Within a family every model has the same ones.
struct ControlTable {
  std::string_view family;
  std::uint16_t operating_mode;        // 1 byte, EEPROM: 1 velocity, 3 position
  std::uint16_t velocity_limit;        // 4 bytes, EEPROM
  std::uint16_t max_position_limit;    // 4 bytes, EEPROM
  std::uint16_t min_position_limit;    // 4 bytes, EEPROM
  std::uint16_t torque_enable;         // 1 byte
  std::uint16_t hardware_error;        // 1 byte, read-only
  std::uint16_t bus_watchdog;          // 1 byte, 20 ms units; -1 (0xFF) once it has fired
  std::uint16_t goal_velocity;         // 4 bytes; goal_velocity.. goal_position+3 is the block halt writes at once:
  std::uint16_t profile_acceleration;  //   goal velocity, profile acceleration, profile velocity, goal position
  std::uint16_t profile_velocity;
  std::uint16_t goal_position;
  std::uint16_t present_velocity;  // 4 bytes, followed by present_position (4 bytes): one read of 8
  std::uint16_t present_position;
};

inline constexpr std::uint16_t kFirstRamAddressX = 64;  // torque enable: everything below is EEPROM

// X-series and MX-series with Protocol 2.0 firmware (e-Manual, "Control Table" of XM430-W350 and MX-28(2.0)).
inline constexpr ControlTable kTableX{"X", 11, 44, 48, 52, 64, 70, 98, 104, 108, 112, 116, 128, 132};
// P-series (PH54, PH42, PM54, PM42: e-Manual "Control Table" of PH54-200-S500-R).
inline constexpr ControlTable kTableP{"P", 11, 44, 48, 52, 512, 518, 546, 552, 556, 560, 564, 576, 580};

inline constexpr std::uint8_t kModeVelocity = 1;
inline constexpr std::uint8_t kModePosition = 3;

struct Model {
  std::uint16_t number;
  std::string_view name;
  const ControlTable* table;
  std::int32_t ticks_per_rev;  // position resolution
  std::int32_t center_tick;    // the tick rcand calls 0 degrees
  double velocity_unit_rpm;    // one unit of goal/present/profile velocity
};

// The model for a model number read at ping, or nullopt (the driver refuses a servo it does not know).
std::optional<Model> find_model(std::uint16_t number);

// Degrees <-> ticks for a model; degrees are relative to the center tick.
std::int32_t ticks_of(const Model& model, double degrees);
double degrees_of(const Model& model, std::int32_t ticks);
// Degrees per second <-> velocity units (rounded, at least 1 for a non-zero speed: 0 means "no limit").
std::int32_t velocity_units_of(const Model& model, double dps);

// "input voltage, overheating" for a Hardware Error Status value; "none" for 0.
std::string hardware_error_text(std::uint8_t bits);

}  // namespace rcand::plugins::dynamixel
