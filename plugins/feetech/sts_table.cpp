#include "sts_table.hpp"

#include <algorithm>
#include <array>
#include <cctype>

namespace rcand::plugins::feetech {

namespace {

// Speeds: STS3215's datasheet no-load 0.222 s/60 deg at 7.4 V = 270 deg/s = 3072 steps/s. STS3250 is faster; rcand
// keeps the same conservative figure for it (a wheel's full speed is settable: wheel_max_rpm).
constexpr std::array kModels{
    Model{"sts3215", 777, 4096, 3072.0},
    Model{"sts3250", 2825, 4096, 3072.0},
};

}  // namespace

std::optional<Model> find_model(std::uint16_t number) {
  for (const auto& model : kModels)
    if (model.number == number) return model;
  return std::nullopt;
}

std::optional<Model> find_model(std::string_view name) {
  for (const auto& model : kModels)
    if (std::equal(name.begin(), name.end(), model.name.begin(), model.name.end(),
                   [](char a, char b) { return std::tolower(static_cast<unsigned char>(a)) == b; }))
      return model;
  return std::nullopt;
}

}  // namespace rcand::plugins::feetech
