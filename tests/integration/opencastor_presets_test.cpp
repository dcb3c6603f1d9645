// Issue 30: the robots people already have. The reference runtime's presets (tests/configs/opencastor/, copied byte
// for byte: README there) run through the real `rcand --check-config` as they are: each passes, or fails only because
// no installed plugin provides a driver protocol its hardware needs, naming exactly those protocols.
#include <doctest/doctest.h>

#include "rcand_process.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

using namespace rcand::test;

namespace {

const std::filesystem::path kPresets = std::filesystem::path(RCAND_SOURCE_DIR) / "tests" / "configs" / "opencastor";
constexpr const char* kCommit = "466a010fd8743b9ab63d5f7d9a804a6fe77679a5";  // the presets' commit (README there)
constexpr const char* kMirror = "/work/.mirror/craigm26+OpenCastor/repo";

// Errors other than a missing driver protocol that a preset still gives (none now): kGap* constants naming each
// exactly, listed in a row's `gaps`, so the table shows what is left of issue 30's measure.

struct Expectation {
  const char* file;
  std::set<std::string> missing;       // driver protocols no installed plugin of rcand's provides: empty = passes
  std::vector<const char*> gaps = {};  // other errors still expected (each at least once), see kGap* above
};

// One row per preset, every preset of the directory.
const std::vector<Expectation>& expectations() {
  static const std::vector<Expectation> table = {
      {"adeept_generic.rcan.yaml", {}},
      {"amazon_kit_generic.rcan.yaml", {}},
      {"arduino_l298n.rcan.yaml", {}},
      {"dynamixel_arm.rcan.yaml", {}},
      {"elegoo_tumbller.rcan.yaml", {}},
      {"esp32_generic.rcan.yaml", {"esp32_websocket"}},
      {"freenove_4wd.rcan.yaml", {}},
      {"groq_rover.rcan.yaml", {}},
      {"hlabs/acb-arm-3dof.rcan.yaml", {"acb"}},
      {"hlabs/acb-biped-6dof.rcan.yaml", {"acb"}},
      {"hlabs/acb-single.rcan.yaml", {"acb"}},
      {"lego_mindstorms_ev3.rcan.yaml", {"ev3dev_tacho_motor", "ev3dev_sensor"}},
      {"lego_spike_prime.rcan.yaml", {"spike_hub_serial", "spike_hub_internal"}},
      {"makeblock_mbot.rcan.yaml", {"makeblock_serial"}},
      {"so_arm101_leader.rcan.yaml", {}},  // its feetech servos: plugins/feetech; its teleop (an arm's) not served
      {"sunfounder_picar.rcan.yaml", {}},
      {"sunfounder_picar_x.rcan.yaml", {"sunfounder_robot_hat", "gpio_hcsr04"}},
      {"taalas_hc1.rcan.yaml", {}},
      {"turtlebot3_burger.rcan.yaml", {"ros2_bridge"}},
      {"turtlebot4.rcan.yaml", {"ros2_bridge", "oakd"}},
      {"unitree_go2.rcan.yaml", {"unitree_sdk2"}},
      {"vex_iq.rcan.yaml", {"vex_iq_serial"}},
      {"waveshare_alpha.rcan.yaml", {"gpio_hcsr04"}},
      {"yahboom_rosmaster.rcan.yaml", {"gpio_hcsr04", "gpio_ws2812", "i2c_mpu6050"}},
  };
  return table;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::string> preset_files() {
  std::vector<std::string> files;
  for (const auto& item : std::filesystem::recursive_directory_iterator(kPresets))
    if (item.path().string().ends_with(".rcan.yaml")) files.push_back(std::filesystem::relative(item.path(), kPresets).string());
  std::sort(files.begin(), files.end());
  return files;
}

// The protocol an error line names as unserved ("... driver protocol 'feetech' (...)"), or "" for any other error.
std::string unserved_protocol(const std::string& line) {
  constexpr std::string_view kUnserved = "no installed plugin provides driver protocol '";
  const auto at = line.find(kUnserved);
  if (at == std::string::npos) return "";
  const auto start = at + kUnserved.size();
  const auto end = line.find('\'', start);
  return end == std::string::npos ? "" : line.substr(start, end - start);
}

}  // namespace

TEST_CASE("the reference runtime's presets: each passes --check-config, or fails only for the driver protocols it names") {
  std::vector<std::string> listed;
  for (const auto& row : expectations()) listed.emplace_back(row.file);
  std::sort(listed.begin(), listed.end());
  CHECK(preset_files() == listed);  // a preset added or gone: the table says what to expect of it

  for (const auto& row : expectations()) {
    INFO(row.file);
    const auto result =
        run_tool(rcand_binary(), {"--check-config", (kPresets / row.file).string(), "--plugin-path", plugin_dir().string()});
    INFO(result.err);
    std::set<std::string> unserved;
    std::set<std::string> gaps_seen;
    std::istringstream lines(result.err);
    for (std::string line; std::getline(lines, line);) {
      if (line.find(": error: ") == std::string::npos) continue;
      if (const std::string protocol = unserved_protocol(line); !protocol.empty()) {
        unserved.insert(protocol);
        continue;
      }
      const auto gap = std::find_if(row.gaps.begin(), row.gaps.end(),
                                    [&line](const char* text) { return line.find(text) != std::string::npos; });
      CHECK_MESSAGE(gap != row.gaps.end(), "an error that is not a missing driver plugin: ", line);
      if (gap != row.gaps.end()) gaps_seen.insert(*gap);
    }
    CHECK(unserved == row.missing);
    CHECK(gaps_seen.size() == row.gaps.size());  // a gap closed: take it out of the table
    const bool passes = row.missing.empty() && row.gaps.empty();
    CHECK(result.exit_code == (passes ? 0 : 1));
    if (passes) CHECK(result.out.find(": OK (capabilities: ") != std::string::npos);
  }
}

TEST_CASE("the presets here are the reference runtime's, byte for byte, when its mirror is on this machine") {
  if (!std::filesystem::exists(kMirror)) return;  // CI: no mirror; the README records the commit
  for (const auto& file : preset_files()) {
    INFO(file);
    const auto original =
        run_tool("/usr/bin/git", {std::string("--git-dir=") + kMirror, "show", std::string(kCommit) + ":config/presets/" + file});
    REQUIRE(original.exit_code == 0);
    CHECK(original.out == read_file(kPresets / file));
  }
}
