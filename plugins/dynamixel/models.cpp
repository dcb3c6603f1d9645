#include "models.hpp"

#include <array>
#include <cmath>

namespace rcand::plugins::dynamixel {

namespace {

// Model numbers and resolutions from the ROBOTIS e-Manual page of each model (cross-checked against the model files of
// ROBOTIS' DynamixelSDK). X and MX(2.0): 4096 ticks centred on 2048, 0.229 rpm per velocity unit; P-series: +-half a
// turn around 0, 0.01 rpm per unit.
constexpr std::array kModels{
    Model{1000, "XH430-W350", &kTableX, 4096, 2048, 0.229},     Model{1001, "XD430-T350", &kTableX, 4096, 2048, 0.229},
    Model{1010, "XH430-W210", &kTableX, 4096, 2048, 0.229},     Model{1011, "XD430-T210", &kTableX, 4096, 2048, 0.229},
    Model{1020, "XM430-W350", &kTableX, 4096, 2048, 0.229},     Model{1030, "XM430-W210", &kTableX, 4096, 2048, 0.229},
    Model{1040, "XH430-V350", &kTableX, 4096, 2048, 0.229},     Model{1050, "XH430-V210", &kTableX, 4096, 2048, 0.229},
    Model{1060, "XL430-W250", &kTableX, 4096, 2048, 0.229},     Model{1070, "XC430-W150", &kTableX, 4096, 2048, 0.229},
    Model{1080, "XC430-W240", &kTableX, 4096, 2048, 0.229},     Model{1090, "2XL430-W250", &kTableX, 4096, 2048, 0.229},
    Model{1100, "XH540-W270", &kTableX, 4096, 2048, 0.229},     Model{1101, "XD540-T270", &kTableX, 4096, 2048, 0.229},
    Model{1110, "XH540-W150", &kTableX, 4096, 2048, 0.229},     Model{1111, "XD540-T150", &kTableX, 4096, 2048, 0.229},
    Model{1120, "XM540-W270", &kTableX, 4096, 2048, 0.229},     Model{1130, "XM540-W150", &kTableX, 4096, 2048, 0.229},
    Model{1140, "XH540-V270", &kTableX, 4096, 2048, 0.229},     Model{1150, "XH540-V150", &kTableX, 4096, 2048, 0.229},
    Model{1160, "2XC430-W250", &kTableX, 4096, 2048, 0.229},    Model{1170, "XW540-T260", &kTableX, 4096, 2048, 0.229},
    Model{1180, "XW540-T140", &kTableX, 4096, 2048, 0.229},     Model{1190, "XL330-M077", &kTableX, 4096, 2048, 0.229},
    Model{1200, "XL330-M288", &kTableX, 4096, 2048, 0.229},     Model{1210, "XC330-T181", &kTableX, 4096, 2048, 0.229},
    Model{1220, "XC330-T288", &kTableX, 4096, 2048, 0.229},     Model{1230, "XC330-M181", &kTableX, 4096, 2048, 0.229},
    Model{1240, "XC330-M288", &kTableX, 4096, 2048, 0.229},     Model{1270, "XW430-T333", &kTableX, 4096, 2048, 0.229},
    Model{1280, "XW430-T200", &kTableX, 4096, 2048, 0.229},     Model{30, "MX-28(2.0)", &kTableX, 4096, 2048, 0.229},
    Model{311, "MX-64(2.0)", &kTableX, 4096, 2048, 0.229},      Model{321, "MX-106(2.0)", &kTableX, 4096, 2048, 0.229},
    Model{2000, "PH42-020-S300-R", &kTableP, 607500, 0, 0.01},  Model{2010, "PH54-100-S500-R", &kTableP, 1003846, 0, 0.01},
    Model{2020, "PH54-200-S500-R", &kTableP, 1003846, 0, 0.01}, Model{2100, "PM42-010-S260-R", &kTableP, 526374, 0, 0.01},
    Model{2110, "PM54-040-S250-R", &kTableP, 502834, 0, 0.01},  Model{2120, "PM54-060-S250-R", &kTableP, 502834, 0, 0.01},
};

}  // namespace

std::optional<Model> find_model(std::uint16_t number) {
  for (const auto& model : kModels)
    if (model.number == number) return model;
  return std::nullopt;
}

std::int32_t ticks_of(const Model& model, double degrees) {
  return model.center_tick + static_cast<std::int32_t>(std::lround(degrees / 360.0 * model.ticks_per_rev));
}

double degrees_of(const Model& model, std::int32_t ticks) {
  return static_cast<double>(ticks - model.center_tick) * 360.0 / model.ticks_per_rev;
}

std::int32_t velocity_units_of(const Model& model, double dps) {
  if (!std::isfinite(dps) || dps == 0.0) return 0;
  const double units = std::abs(dps) / 6.0 / model.velocity_unit_rpm;  // deg/s -> rpm -> units
  const auto rounded = std::max<std::int32_t>(1, static_cast<std::int32_t>(std::min(std::lround(units), 1L << 30)));
  return dps < 0 ? -rounded : rounded;
}

std::string hardware_error_text(std::uint8_t bits) {
  // Hardware Error Status bits (X-series e-Manual, address 70).
  static constexpr std::array<const char*, 8> kBits{"input voltage",    "bit 1",    "overheating", "motor encoder",
                                                    "electrical shock", "overload", "bit 6",       "bit 7"};
  if (bits == 0) return "none";
  std::string text;
  for (unsigned i = 0; i < kBits.size(); ++i)
    if (bits & (1u << i)) text += (text.empty() ? "" : ", ") + std::string(kBits[i]);
  return text;
}

}  // namespace rcand::plugins::dynamixel
