// Claims: the hardware a setting names (a GPIO line on a chip, an I2C address on a bus, a servo id on a serial bus),
// declared in a manifest's settings schema with "x-claim", so two settings that name the same thing - in one driver
// entry or in two - are refused before anything is opened: a pin driven by two drivers moves the wrong motor. The
// kinds are a fixed vocabulary, so a vendor's plugin and rcand's own find each other's claims. Pure and header-only;
// part of the settings contract (settings.hpp).
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::sdk::contract {

// One thing an instance's settings name: its kind, where it lives (the scope: a chip, a bus, ...; null where the
// settings leave it to be found at start, which compares equal to any), what it is, and the setting that names it.
struct Claim {
  std::string resource;               // a kind of ResourceKinds: "gpio-line"
  std::vector<nlohmann::json> scope;  // normalised: "gpiochip0", "/dev/i2c-1", 64
  nlohmann::json value;               // normalised: 17, "GPIO17", 64
  std::string key;                    // the setting, from the instance's root: "channels.left.in1"
};

namespace claim_detail {

enum class Form { Text, Integer, GpioChip, I2cBus, I2cAddress };

struct ResourceKind {
  std::string_view name;
  std::vector<Form> scope;  // one form per scope item
  Form value = Form::Text;
  bool one_instance = false;  // names: unique within one instance only
  std::string_view summary;   // for manifests and docs
};

inline const std::vector<ResourceKind>& kinds() {
  static const std::vector<ResourceKind> table{
      {"gpio-line", {Form::GpioChip}, Form::Text, false, "a GPIO line (offset or name) on a chip"},
      {"pwm-output", {Form::Integer}, Form::Integer, false, "a /sys/class/pwm channel of a pwmchip"},
      {"i2c-address", {Form::I2cBus}, Form::I2cAddress, false, "a device address on an I2C bus"},
      {"i2c-channel",
       {Form::I2cBus, Form::I2cAddress},
       Form::Integer,
       false,
       "an output channel of the device at a bus and address"},
      {"serial-port", {}, Form::Text, false, "a serial device (one driver talks on it)"},
      {"serial-id", {Form::Text}, Form::Integer, false, "a device id on the bus of a serial port"},
      {"name", {}, Form::Text, true, "a name given once in one driver entry (a joint, a wheel)"},
  };
  return table;
}

inline const ResourceKind* find_kind(std::string_view name) {
  for (const auto& kind : kinds())
    if (kind.name == name) return &kind;
  return nullptr;
}

inline std::optional<long long> integer_of(const nlohmann::json& value) {
  if (value.is_number_integer()) return value.get<long long>();
  if (!value.is_string()) return std::nullopt;
  const std::string text = value.get<std::string>();
  if (text.empty()) return std::nullopt;
  try {
    std::size_t used = 0;
    const long long number = std::stoll(text, &used, 0);  // "0x40", "64"
    if (used == text.size()) return number;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

inline bool all_digits(std::string_view text) {
  return !text.empty() && std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c); });
}

// The same chip, bus or address written the ways rcand accepts it compares equal: 0, "gpiochip0", "/dev/gpiochip0".
inline nlohmann::json normalise(Form form, const nlohmann::json& value) {
  if (value.is_null()) return value;
  switch (form) {
    case Form::Text: return value;
    case Form::Integer:
    case Form::I2cAddress:
      if (const auto number = integer_of(value)) return *number;
      return value;
    case Form::GpioChip: {
      if (value.is_number_integer()) return "gpiochip" + std::to_string(value.get<long long>());
      std::string text = value.is_string() ? value.get<std::string>() : value.dump();
      if (text.starts_with("/dev/")) text = text.substr(5);
      return all_digits(text) ? "gpiochip" + text : text;
    }
    case Form::I2cBus: {
      if (value.is_number_integer()) return "/dev/i2c-" + std::to_string(value.get<long long>());
      std::string text = value.is_string() ? value.get<std::string>() : value.dump();
      if (all_digits(text)) return "/dev/i2c-" + text;
      if (text.starts_with("i2c-")) return "/dev/" + text;
      return text;
    }
  }
  return value;
}

inline std::string shown(Form form, const nlohmann::json& value) {
  if (value.is_null()) return "(found at start)";
  if (form == Form::I2cAddress && value.is_number_integer()) {
    char text[16];
    std::snprintf(text, sizeof text, "0x%02llx", static_cast<unsigned long long>(value.get<long long>()));
    return text;
  }
  return value.is_string() ? value.get<std::string>() : value.dump();
}

// "GPIO line 17 on gpiochip0", "channel 3 of the I2C device 0x40 on /dev/i2c-1".
inline std::string describe(const ResourceKind& kind, const Claim& claim) {
  auto scope = [&](std::size_t i) { return i < claim.scope.size() ? shown(kind.scope[i], claim.scope[i]) : std::string("?"); };
  const std::string value = shown(kind.value, claim.value);
  if (kind.name == "gpio-line") return "GPIO line " + value + " on chip " + scope(0);
  if (kind.name == "pwm-output") return "PWM channel " + value + " of pwmchip" + scope(0);
  if (kind.name == "i2c-address") return "I2C address " + value + " on " + scope(0);
  if (kind.name == "i2c-channel") return "channel " + value + " of the I2C device " + scope(1) + " on " + scope(0);
  if (kind.name == "serial-port") return "serial port " + value;
  if (kind.name == "serial-id") return "id " + value + " on the serial bus " + scope(0);
  return "'" + value + "'";
}

}  // namespace claim_detail

// The kinds a manifest may claim, with what each is ("gpio-line": "a GPIO line (offset or name) on a chip").
inline std::vector<std::pair<std::string, std::string>> claim_kinds() {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& kind : claim_detail::kinds()) out.emplace_back(kind.name, kind.summary);
  return out;
}

// The claims of one instance (a driver entry), as the host names it.
struct InstanceClaims {
  std::string where;  // "drivers[1]"
  std::string label;  // "driver arm0", for the message
  std::vector<Claim> claims;
};

// A claim that names what an earlier one already named.
struct ClaimConflict {
  std::size_t instance = 0;  // index into the instances given
  std::string key;           // the later claim's setting ("channels.right.in1")
  std::string problem;  // "GPIO line 17 on chip gpiochip0 is already claimed by drivers[0].channels.left.in1 (driver wheels)"
};

// Every claim that names a thing claimed before it (in this order), within one instance or across instances. A scope
// left to be found at start (null) could be any: it conflicts with every scope, and the message says so.
inline std::vector<ClaimConflict> claim_conflicts(const std::vector<InstanceClaims>& instances) {
  std::vector<ClaimConflict> conflicts;
  for (std::size_t i = 0; i < instances.size(); ++i) {
    for (std::size_t c = 0; c < instances[i].claims.size(); ++c) {
      const Claim& claim = instances[i].claims[c];
      const auto* kind = claim_detail::find_kind(claim.resource);
      if (kind == nullptr) continue;
      bool found = false;
      for (std::size_t j = kind->one_instance ? i : 0; j <= i && !found; ++j) {
        const std::size_t end = j == i ? c : instances[j].claims.size();
        for (std::size_t d = 0; d < end && !found; ++d) {
          const Claim& earlier = instances[j].claims[d];
          if (earlier.resource != claim.resource || earlier.value != claim.value || earlier.scope.size() != claim.scope.size())
            continue;
          bool unknown_scope = false, same = true;
          for (std::size_t s = 0; s < claim.scope.size() && same; ++s) {
            if (claim.scope[s].is_null() || earlier.scope[s].is_null()) unknown_scope = true;
            else same = claim.scope[s] == earlier.scope[s];
          }
          if (!same) continue;
          found = true;
          std::string problem = claim_detail::describe(*kind, claim) + " is already claimed by ";
          problem += j == i ? earlier.key : instances[j].where + "." + earlier.key + " (" + instances[j].label + ")";
          if (kind->one_instance)
            problem = claim_detail::describe(*kind, claim) + " is given twice (first at " + earlier.key + ")";
          if (unknown_scope)
            problem += "; one of them leaves the " + std::string(kind->name == "gpio-line" ? "chip" : "bus") +
                       " to be found at start, so it may be the same: set it to tell them apart";
          conflicts.push_back({i, claim.key, std::move(problem)});
        }
      }
    }
  }
  return conflicts;
}

}  // namespace rcand::sdk::contract
