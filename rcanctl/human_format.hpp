// Values as people read them in rcanctl's tables (--json keeps the robot's numbers): times in the local zone as ISO
// 8601, numbers as people write them (0, not 1.6e-17; 0.25, not 0.25000000000000006).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

namespace rcand::rcanctl {

// Milliseconds since the Unix epoch as local ISO 8601 with the offset: "2026-11-28T01:02:03.456+01:00".
std::string local_time(std::int64_t epoch_ms);

// A number rounded to `decimals` places, trailing zeros dropped, never in exponent form, "-0" as "0".
std::string human_number(double value, int decimals = 3);

// A JSON value for a table cell: "-" for null, strings as they are, numbers by human_number, yes/no for booleans,
// anything else as compact JSON.
std::string human_text(const nlohmann::json& value);

// A timestamp field (ms since the epoch) for a table cell: local_time, or "-" when it is not a number.
std::string human_time(const nlohmann::json& epoch_ms);

}  // namespace rcand::rcanctl
