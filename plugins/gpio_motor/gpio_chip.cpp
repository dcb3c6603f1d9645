#include "gpio_chip.hpp"

namespace rcand::plugins::gpio_motor {

std::string describe(const LineRef& line) {
  if (const auto* offset = std::get_if<unsigned>(&line)) return "line " + std::to_string(*offset);
  return "line \"" + std::get<std::string>(line) + "\"";
}

}  // namespace rcand::plugins::gpio_motor
