#include "human_format.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>

namespace rcand::rcanctl {

std::string local_time(std::int64_t epoch_ms) {
  const std::time_t seconds = static_cast<std::time_t>(epoch_ms / 1000 - (epoch_ms % 1000 < 0 ? 1 : 0));
  const int millis = static_cast<int>(((epoch_ms % 1000) + 1000) % 1000);
  std::tm local{};
  if (::localtime_r(&seconds, &local) == nullptr) return std::to_string(epoch_ms);
  char date[32], zone[8];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%S", &local);
  std::strftime(zone, sizeof zone, "%z", &local);  // +0100: ISO 8601 writes it +01:00
  const std::string offset(zone);
  char text[64];
  std::snprintf(text, sizeof text, "%s.%03d%s:%s", date, millis, offset.substr(0, 3).c_str(),
                offset.size() >= 5 ? offset.substr(3, 2).c_str() : "00");
  return text;
}

std::string human_number(double value, int decimals) {
  if (!std::isfinite(value)) return std::isnan(value) ? "nan" : value > 0 ? "inf" : "-inf";
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  std::string number = text;
  if (number.find('.') != std::string::npos) {
    while (number.back() == '0') number.pop_back();
    if (number.back() == '.') number.pop_back();
  }
  return number == "-0" ? "0" : number;
}

std::string human_text(const nlohmann::json& value) {
  if (value.is_null()) return "-";
  if (value.is_string()) return value.get<std::string>();
  if (value.is_boolean()) return value.get<bool>() ? "yes" : "no";
  if (value.is_number_float()) return human_number(value.get<double>());
  return value.dump();  // integers exactly; objects and arrays compact
}

std::string human_time(const nlohmann::json& epoch_ms) {
  return epoch_ms.is_number() ? local_time(epoch_ms.get<std::int64_t>()) : "-";
}

}  // namespace rcand::rcanctl
