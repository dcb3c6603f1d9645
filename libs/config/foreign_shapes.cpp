#include "libs/config/foreign_shapes.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <map>
#include <optional>
#include <string_view>
#include <utility>

namespace rcand::config {
namespace foreign_shapes_detail {

using nlohmann::json;
using yaml::ConfigDiagnostic;
using yaml::SourceMark;
using Marks = std::map<std::string, SourceMark>;

bool same_text(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// The marks of `from` and of every key below it, as if written at `to` ("cameras.main.url" -> "camera.url").
void copy_marks(const Marks& source, Marks& target, const std::string& from, const std::string& to) {
  for (auto it = source.lower_bound(from); it != source.end() && it->first.starts_with(from); ++it) {
    const std::string_view rest = std::string_view(it->first).substr(from.size());
    if (rest.empty() || rest.front() == '.' || rest.front() == '[') target[to + std::string(rest)] = it->second;
  }
}

void erase_marks(Marks& marks, const std::string& prefix) {
  for (auto it = marks.lower_bound(prefix); it != marks.end() && it->first.starts_with(prefix);) {
    const std::string_view rest = std::string_view(it->first).substr(prefix.size());
    if (rest.empty() || rest.front() == '.' || rest.front() == '[') it = marks.erase(it);
    else ++it;
  }
}

std::string item(const std::string& parent, std::size_t index) { return parent + "[" + std::to_string(index) + "]"; }

std::string single_quoted(std::string_view text) { return "'" + std::string(text) + "'"; }

class ShapeReader {
 public:
  ShapeReader(yaml::YamlDocument& document, const std::string& file, std::vector<ConfigDiagnostic>& notes)
      : doc_(document.doc), marks_(document.marks), file_(file), notes_(notes) {}

  void run() {
    if (!doc_.is_object()) return;
    read_cameras_block();
    read_drivers();
    read_camera_type();
    read_links();
    read_arm_teleop();
  }

 private:
  // One driver entry of the rewritten list and where its keys were written.
  struct NewEntry {
    json value;
    std::vector<std::pair<std::string, std::string>> marks;  // {old key path, new key path relative to the entry}
  };

  // At `key_path`'s mark; the message names the key itself (it reads as a sentence about it).
  void note(const std::string& key_path, std::string message) {
    notes_.push_back({ConfigDiagnostic::Severity::Warning, yaml::nearest_mark(marks_, file_, key_path), "", std::move(message)});
  }

  // "640x480" -> [640, 480]; a list as it is.
  static json resolution_of(const json& value) {
    if (!value.is_string()) return value;
    const auto& text = value.get_ref<const std::string&>();
    const auto x = text.find_first_of("xX");
    try {
      if (x != std::string::npos && x > 0) return json::array({std::stoi(text.substr(0, x)), std::stoi(text.substr(x + 1))});
    } catch (const std::exception&) {
    }
    return value;
  }

  // The reference runtime's camera keys as the `camera` block's: {type, device, url, resolution, fps, ...}; the keys
  // with no counterpart are named in `dropped`. `from` is where the block was written.
  json camera_from(const json& source, const std::string& from, std::string default_type, std::string& dropped) {
    json camera = json::object();
    Marks moved;
    for (const auto& [key, value] : source.items()) {
      std::string target = key;
      if (key == "index") target = "device";
      else if (key == "protocol" || key == "sensor_type") continue;  // what it is, said by `type` below
      else if (key == "id" || key == "role" || key == "enabled") continue;
      else if (key == "type" || key == "device" || key == "url" || key == "resolution" || key == "fps" || key == "framerate" ||
               key == "fourcc" || key == "width" || key == "height" || key == "path")
        target = key;
      else {
        dropped += (dropped.empty() ? "" : ", ") + key;
        continue;
      }
      camera[target] = key == "resolution" ? resolution_of(value) : value;
      copy_marks(marks_, moved, yaml::child_path(from, key), "camera." + target);
    }
    // The reference runtime's `http` camera polls a URL that answers one JPEG per request: rcand's snapshot camera
    // (rcand's own `http` is a stream, MJPEG through FFmpeg).
    if (camera.contains("type") && camera["type"].is_string() && same_text(camera["type"].get<std::string>(), "http")) {
      camera["type"] = "snapshot";
      note(from + ".type", from + ".type 'http' (another runtime's snapshot camera: one JPEG per request) is read as " +
                               "'snapshot'; write 'snapshot' to say so");
    }
    if (!camera.contains("type") && !default_type.empty()) camera["type"] = std::move(default_type);
    if (!camera.contains("type") && camera.contains("url")) camera["type"] = "url";
    copy_marks(marks_, moved, from, "camera");
    erase_marks(marks_, "camera");
    for (auto& [key, mark] : moved) marks_[key] = mark;
    marks_["camera"] = yaml::nearest_mark(marks_, file_, from);
    return camera;
  }

  // `cameras:` -> `camera` (docs/protocol.md §10.3): the primary camera, else `main`, else the first.
  void read_cameras_block() {
    const auto it = doc_.find("cameras");
    if (it == doc_.end()) return;
    const json& cameras = *it;
    std::vector<std::pair<std::string, const json*>> found;  // {key path, block}
    if (cameras.is_object())
      for (const auto& [name, block] : cameras.items()) found.emplace_back("cameras." + name, &block);
    else if (cameras.is_array())
      for (std::size_t i = 0; i < cameras.size(); ++i) found.emplace_back(item("cameras", i), &cameras[i]);
    found.erase(std::remove_if(found.begin(), found.end(), [](const auto& entry) { return !entry.second->is_object(); }),
                found.end());
    if (found.empty()) return;  // nothing to read: left to the warning of ignored keys
    if (doc_.contains("camera")) {
      note("cameras", "cameras (another runtime's list of cameras) is ignored: the `camera` block is the robot's camera");
      return;
    }
    auto chosen = std::find_if(found.begin(), found.end(), [](const auto& entry) {
      return entry.second->is_object() && entry.second->value("role", json()) == "primary";
    });
    if (chosen == found.end())
      chosen = std::find_if(found.begin(), found.end(), [](const auto& entry) { return entry.first == "cameras.main"; });
    if (chosen == found.end()) chosen = found.begin();
    std::string dropped;
    const std::string from = chosen->first;
    json camera = camera_from(*chosen->second, from, "", dropped);
    std::string message = from + " is read as rcand's `camera` block (plugin org.rcand.vision serves one camera)";
    if (!dropped.empty()) message += "; its keys " + dropped + " have no counterpart and are ignored";
    if (found.size() > 1) message += "; the other " + std::to_string(found.size() - 1) + " camera(s) are not served";
    note(from, message + "; write `camera:` to say so");
    doc_.erase("cameras");
    erase_marks(marks_, "cameras");
    doc_["camera"] = std::move(camera);
  }

  // physics.kinematics[] links as the reference runtime writes them ({id, limits_deg: [min, max]}) also say
  // {joint, min_deg, max_deg}, what the arm and the servo drivers read.
  void read_links() {
    const auto physics = doc_.find("physics");
    if (physics == doc_.end() || !physics->is_object() || !physics->contains("kinematics")) return;
    json& links = (*physics)["kinematics"];
    if (!links.is_array()) return;
    std::string named;
    for (std::size_t i = 0; i < links.size(); ++i) {
      json& link = links[i];
      if (!link.is_object() || link.contains("joint") || !link.contains("id") || !link["id"].is_string()) continue;
      const auto limits = link.find("limits_deg");
      if (limits == link.end() || !limits->is_array() || limits->size() != 2 || !(*limits)[0].is_number() ||
          !(*limits)[1].is_number())
        continue;
      const std::string path = item("physics.kinematics", i);
      link["joint"] = link["id"];
      link["min_deg"] = (*limits)[0];
      link["max_deg"] = (*limits)[1];
      if (const auto mark = marks_.find(path + ".id"); mark != marks_.end()) marks_[path + ".joint"] = mark->second;
      if (const auto mark = marks_.find(path + ".limits_deg"); mark != marks_.end())
        marks_[path + ".min_deg"] = marks_[path + ".max_deg"] = mark->second;
      named += (named.empty() ? "" : ", ") + link["id"].get<std::string>();
    }
    if (!named.empty())
      note("physics.kinematics", "physics.kinematics links " + named +
                                     " (another runtime's {id, limits_deg}) are read "
                                     "as joints {joint, min_deg, max_deg}; write those to say so");
  }

  // `teleop` listed for an arm (physics.type arm, no locomotion) is the reference runtime's leader/follower
  // teleoperation of the joints; rcand's teleop capability drives a base (a differential_drive), so on an arm it is
  // not served: taken out of the list with one warning, as nav without its physics is (§9.5); --strict refuses it.
  void read_arm_teleop() {
    const auto physics = doc_.find("physics");
    const auto protocol = doc_.find("rcan_protocol");
    if (physics == doc_.end() || !physics->is_object() || physics->value("type", json()) != "arm" || protocol == doc_.end() ||
        !protocol->is_object())
      return;
    const auto listed = protocol->find("capabilities");
    if (listed == protocol->end() || !listed->is_array()) return;
    const auto teleop = std::find(listed->begin(), listed->end(), json("teleop"));
    if (teleop == listed->end()) return;
    const auto index = static_cast<std::size_t>(teleop - listed->begin());
    const std::string at = item("rcan_protocol.capabilities", index);
    note(at, at + ": teleop on an arm (physics.type arm: the reference runtime's leader/follower teleoperation of its "
                  "joints) is not served: rcand's teleop drives a base (a differential_drive actuator), the joints "
                  "are served by arm; taken out of the capabilities");
    Marks old;
    copy_marks(marks_, old, "rcan_protocol.capabilities", "rcan_protocol.capabilities");
    erase_marks(marks_, "rcan_protocol.capabilities");
    marks_["rcan_protocol.capabilities"] = old["rcan_protocol.capabilities"];
    for (std::size_t i = 0, j = 0; i < listed->size(); ++i) {
      if (i == index) continue;
      copy_marks(old, marks_, item("rcan_protocol.capabilities", i), item("rcan_protocol.capabilities", j++));
    }
    listed->erase(teleop);
  }

  // The reference runtime's names of the Raspberry Pi camera (a V4L2 device through libcamera) as camera.type; a
  // Luxonis OAK camera, which only Luxonis' DepthAI library reads (not in Debian), as a driver of protocol 'oakd'
  // that no plugin of rcand's provides (--check-config names it), not as the vision plugin's camera.
  void read_camera_type() {
    const auto camera = doc_.find("camera");
    if (camera == doc_.end() || !camera->is_object()) return;
    const auto type = camera->find("type");
    if (type == camera->end() || !type->is_string()) return;
    const std::string written = type->get<std::string>();
    if (same_text(written, "oakd") || same_text(written, "oak-d") || same_text(written, "oak") || same_text(written, "depthai")) {
      json driver = *camera;
      driver.erase("type");
      driver["id"] = "camera";
      driver["protocol"] = "oakd";
      if (!doc_.contains("drivers") || !doc_["drivers"].is_array()) doc_["drivers"] = json::array();
      const std::string target = item("drivers", doc_["drivers"].size());
      Marks moved;
      copy_marks(marks_, moved, "camera", target);
      for (auto& [key, mark] : moved) marks_[key] = mark;
      marks_[target + ".protocol"] = yaml::nearest_mark(marks_, file_, "camera.type");
      doc_["drivers"].push_back(std::move(driver));
      note("camera.type", "camera.type " + single_quoted(written) +
                              " (a Luxonis OAK camera: its frames and depth come through Luxonis' DepthAI, which "
                              "rcand's vision plugin has no source for) is read as " +
                              target +
                              ", a driver of "
                              "protocol 'oakd'");
      doc_.erase("camera");
      erase_marks(marks_, "camera");
      return;
    }
    if (!same_text(written, "picam") && !same_text(written, "picamera") && !same_text(written, "picamera2")) return;
    *type = "csi";
    note("camera.type", "camera.type " + single_quoted(written) +
                            " (another runtime's name of the Raspberry Pi camera) is "
                            "read as 'csi'; write 'csi' to say so");
  }

  static std::optional<std::string> camera_protocol_type(const json& entry) {
    static constexpr std::array<std::pair<std::string_view, std::string_view>, 9> kCameraProtocols{{
        {"v4l2", "v4l2"},
        {"usb_camera", "usb"},
        {"usb", "usb"},
        {"webcam", "webcam"},
        {"picamera", "csi"},
        {"picamera2", "csi"},
        {"picam", "csi"},
        {"mjpeg_stream", "url"},
        {"http", "snapshot"},  // the reference runtime's http camera polls snapshots
    }};
    const auto protocol = entry.find("protocol");
    if (protocol == entry.end() || !protocol->is_string()) return std::nullopt;
    for (const auto& [name, type] : kCameraProtocols)
      if (same_text(name, protocol->get_ref<const std::string&>())) return std::string(type);
    return std::nullopt;
  }

  static bool disabled(const json& entry) {
    const auto enabled = entry.find("enabled");
    return enabled != entry.end() && *enabled == false;
  }

  // A per-servo entry of the reference runtime: one servo (hardware_id) of a bus (port).
  static bool per_servo(const json& entry) {
    return entry.contains("hardware_id") && entry["hardware_id"].is_number_integer() && entry.contains("port") &&
           entry["port"].is_string() && entry.contains("protocol") && entry["protocol"].is_string() && !entry.contains("servos");
  }

  // The link's limits_deg from physics.kinematics ({id, limits_deg: [min, max]}).
  std::optional<std::pair<json, json>> link_limits(const std::string& link) const {
    const auto physics = doc_.find("physics");
    if (physics == doc_.end() || !physics->is_object()) return std::nullopt;
    const auto kinematics = physics->find("kinematics");
    if (kinematics == physics->end() || !kinematics->is_array()) return std::nullopt;
    for (const auto& item : *kinematics) {
      if (!item.is_object() || item.value("id", json()) != link) continue;
      const auto limits = item.find("limits_deg");
      if (limits != item.end() && limits->is_array() && limits->size() == 2 && (*limits)[0].is_number() &&
          (*limits)[1].is_number())
        return std::pair((*limits)[0], (*limits)[1]);
    }
    return std::nullopt;
  }

  // Per-servo keys the reference runtime writes that a bus plugin of rcand reads under the same name in each
  // `servos[]` item (plugins/feetech/settings.cpp); every other per-servo key is named as ignored.
  static bool servo_key_carried(std::string_view protocol, std::string_view key) {
    static constexpr std::array<std::string_view, 3> kFeetech{"model", "max_velocity_dps", "torque_limit_pct"};
    return same_text(protocol, "feetech") && std::find(kFeetech.begin(), kFeetech.end(), key) != kFeetech.end();
  }

  // Per-servo entries of one protocol on one port: one bus entry at the first one's place.
  NewEntry merge_servos(const json& drivers, const std::vector<std::size_t>& members, int bus_index) {
    const json& first = drivers[members.front()];
    const std::string protocol = first["protocol"].get<std::string>();
    const std::string port = first["port"].get<std::string>();
    const std::string first_path = item("drivers", members.front());
    NewEntry bus;
    bus.value = {{"id", protocol + "_bus" + std::to_string(bus_index)}, {"protocol", protocol}, {"port", port}};
    bus.marks = {{first_path, ""}, {first_path + ".protocol", ".protocol"}, {first_path + ".port", ".port"}};
    if (first.contains("baud_rate")) {
      bus.value["baud_rate"] = first["baud_rate"];
      bus.marks.emplace_back(first_path + ".baud_rate", ".baud_rate");
    }
    json servos = json::array();
    std::string listed, dropped, limits_from;
    for (std::size_t k = 0; k < members.size(); ++k) {
      const json& entry = drivers[members[k]];
      const std::string path = item("drivers", members[k]);
      const std::string servo_path = ".servos[" + std::to_string(k) + "]";
      json servo = {{"id", entry["hardware_id"]}};
      bus.marks.emplace_back(path, servo_path);
      bus.marks.emplace_back(path + ".hardware_id", servo_path + ".id");
      std::string joint;
      if (entry.contains("link_id") && entry["link_id"].is_string()) {
        joint = entry["link_id"].get<std::string>();
        bus.marks.emplace_back(path + ".link_id", servo_path + ".joint");
      } else if (entry.contains("id") && entry["id"].is_string()) {
        joint = entry["id"].get<std::string>();
        bus.marks.emplace_back(path + ".id", servo_path + ".joint");
      } else {
        joint = "joint" + std::to_string(k);
      }
      servo["joint"] = joint;
      if (const auto limits = link_limits(joint)) {
        servo["min_deg"] = limits->first;
        servo["max_deg"] = limits->second;
        limits_from += (limits_from.empty() ? "" : ", ") + joint;
      }
      for (const auto& [key, value] : entry.items()) {
        if (servo_key_carried(protocol, key)) {
          servo[key] = value;
          bus.marks.emplace_back(path + "." + key, servo_path + "." + key);
        } else if (key != "id" && key != "protocol" && key != "port" && key != "baud_rate" && key != "hardware_id" &&
                   key != "link_id" && dropped.find(key) == std::string::npos) {
          dropped += (dropped.empty() ? "" : ", ") + key;
        }
      }
      if (entry.contains("baud_rate") && entry["baud_rate"] != first.value("baud_rate", json()))
        bus.value["baud_rate"] = entry["baud_rate"];  // one bus, one speed: left for the plugin to refuse if unlike
      listed += (listed.empty() ? "" : ", ") + entry["hardware_id"].dump() + " " + joint;
      servos.push_back(std::move(servo));
    }
    bus.value["servos"] = std::move(servos);
    std::string message = std::to_string(members.size()) + " per-servo entries of protocol " + single_quoted(protocol) + " on " +
                          port + " (another runtime's shape) are read as one bus, driver " +
                          single_quoted(bus.value["id"].get<std::string>()) + " with servos [" + listed +
                          "] (id from hardware_id, joint from link_id";
    if (!limits_from.empty()) message += ", limits from physics.kinematics[].limits_deg of " + limits_from;
    message += ")";
    if (!dropped.empty()) message += "; per-servo keys " + dropped + " have no counterpart and are ignored";
    note(first_path, first_path + ": " + message + "; write one entry with `servos:` to say so");
    return bus;
  }

  // The reference runtime writes an Arduino bridge's peripherals as entries of their own on the board's port
  // (`sensor_type: hcsr04`, `servo`, `digital_array`); rcand's arduino_serial_json driver is the board, one entry.
  static bool arduino_entry(const json& entry) {
    return entry.is_object() && entry.contains("protocol") && entry["protocol"].is_string() &&
           same_text(entry["protocol"].get<std::string>(), "arduino_serial_json") && entry.contains("port") &&
           entry["port"].is_string();
  }
  static bool arduino_peripheral(const json& entry) { return arduino_entry(entry) && entry.contains("sensor_type"); }

  // The wiring an Arduino bridge's board entry records in shapes of its own: `channels` keys that are not the six
  // rcand's driver takes (per wheel: fl_pwm, fl_dir, ...; or motor names M1, M2) and pin keys at the entry's top
  // level (left_pwm_pin, left_in1, ...). The bridge firmware fixes its pins and rcand sends it wheel speeds, so they
  // mean nothing to rcand: named once and ignored.
  void drop_arduino_pins(NewEntry& board, const std::string& named) {
    static constexpr std::array<std::string_view, 6> kChannels{"left_pwm_pin",  "left_dir_a",  "left_dir_b",
                                                               "right_pwm_pin", "right_dir_a", "right_dir_b"};
    json& value = board.value;
    std::string dropped;
    if (const auto channels = value.find("channels"); channels != value.end() && channels->is_object()) {
      const bool own = std::all_of(channels->items().begin(), channels->items().end(), [](const auto& channel) {
        return std::find(kChannels.begin(), kChannels.end(), channel.key()) != kChannels.end();
      });
      if (!own) {
        dropped = "channels " + channels->dump();
        value.erase(channels);
      }
    }
    std::vector<std::string> pins;
    for (const auto& [key, pin] : value.items()) {
      const std::string_view name = key;
      if (name.ends_with("_pin") || name.ends_with("_in1") || name.ends_with("_in2") || name == "motor_driver_ic")
        pins.push_back(key);
    }
    for (const auto& key : pins) {
      dropped += (dropped.empty() ? "" : ", ") + key + " " + value[key].dump();
      value.erase(key);
    }
    if (!dropped.empty())
      note(board.marks.front().first, named + ": " + dropped +
                                          " (the wiring, as the reference runtime records it) are fixed by the "
                                          "bridge firmware, to which rcand's arduino_serial_json driver sends wheel "
                                          "speeds: ignored");
  }

  static bool gpio_entry(const json& entry) {
    const auto protocol = entry.find("protocol");
    return protocol != entry.end() && protocol->is_string() && same_text(protocol->get_ref<const std::string&>(), "gpio");
  }

  // A `gpio` entry of the reference runtime that is no GPIO H-bridge: the SunFounder Robot HAT (`interface: i2c`, its
  // microcontroller at 0x14 drives the motors and servos), or a sensor (`sensor_type`). The HAT and an HC-SR04 are
  // read as the protocols of that hardware, which no plugin of rcand's serves (--check-config names them); the other
  // sensors have no counterpart in rcand and are ignored. Returns false when the entry stays as written.
  bool read_gpio_shape(json& entry, const std::string& path, const std::string& named) {
    if (!gpio_entry(entry)) return false;
    const auto interface = entry.find("interface");
    if (interface != entry.end() && *interface == "i2c") {
      entry["protocol"] = "sunfounder_robot_hat";
      const json address = entry.value("address", json("?"));
      note(path, named + " (protocol 'gpio', interface i2c, address " +
                     (address.is_string() ? address.get<std::string>() : address.dump()) +
                     ") is the SunFounder Robot HAT's motor and servo controller, not GPIO lines: read as protocol "
                     "'sunfounder_robot_hat'");
      return true;
    }
    const auto type = entry.find("sensor_type");
    if (type == entry.end() || !type->is_string()) return false;
    if (*type == "hcsr04") {
      entry["protocol"] = "gpio_hcsr04";
      note(path, named + " (protocol 'gpio', sensor_type hcsr04) is an HC-SR04 on GPIO lines: read as protocol 'gpio_hcsr04'");
      return true;
    }
    note(path, named + " (protocol 'gpio', sensor_type " + type->dump() +
                   ") is a sensor or output rcand has no counterpart for: ignored");
    entry = json();  // dropped
    return true;
  }

  // A TB6612 on GPIO lines in the reference runtime's shape, channels {ain1_gpio, ain2_gpio, pwma_gpio?, bin1_gpio,
  // bin2_gpio, pwmb_gpio?, standby_gpio?}: motor A left, B right, each PWM input its motor's enable (on at full
  // speed: a Raspberry Pi drives a line, a speed needs a hardware PWM, `pwm`), STBY the shared `standby` line.
  bool read_tb6612_gpio(json& entry, const std::string& path, const std::string& named, NewEntry& rewritten) {
    const auto channels = entry.find("channels");
    if (!gpio_entry(entry) || channels == entry.end() || !channels->is_object()) return false;
    for (const char* key : {"ain1_gpio", "ain2_gpio", "bin1_gpio", "bin2_gpio"})
      if (!channels->contains(key)) return false;
    static constexpr std::array<std::pair<std::string_view, std::string_view>, 7> kLines{{
        {"ain1_gpio", ".channels.left.in1"},
        {"ain2_gpio", ".channels.left.in2"},
        {"pwma_gpio", ".channels.left.enable"},
        {"bin1_gpio", ".channels.right.in1"},
        {"bin2_gpio", ".channels.right.in2"},
        {"pwmb_gpio", ".channels.right.enable"},
        {"standby_gpio", ".standby"},
    }};
    json left = json::object(), right = json::object(), standby;
    for (const auto& channel : channels->items()) {
      const std::string& name = channel.key();
      const json& line = channel.value();
      const auto found = std::find_if(kLines.begin(), kLines.end(), [&name](const auto& known) { return known.first == name; });
      if (found == kLines.end()) return false;  // a key of its own: left for the plugin to name
      const std::string target(found->second);
      if (target == ".standby") standby = line;
      else (target.starts_with(".channels.left") ? left : right)[target.substr(target.rfind('.') + 1)] = line;
      rewritten.marks.emplace_back(path + ".channels." + name, target);
    }
    std::string message = named + ": channels " + channels->dump() +
                          " (a TB6612 on GPIO lines, the reference runtime's shape) are read as channels {left: "
                          "{in1: ain1, in2: ain2, enable: pwma}, right: {in1: bin1, in2: bin2, enable: pwmb}}";
    entry["channels"] = {{"left", std::move(left)}, {"right", std::move(right)}};
    if (!standby.is_null()) {
      entry["standby"] = std::move(standby);
      message += ", standby from standby_gpio";
    }
    message += " (the PWM inputs on at full speed: a speed needs a hardware PWM, channels.<side>.pwm)";
    std::string dropped;
    for (const char* key : {"pwm_freq_hz", "pwm_range"})
      if (entry.contains(key)) {
        dropped += (dropped.empty() ? "" : ", ") + std::string(key);
        entry.erase(key);
      }
    if (!dropped.empty()) message += "; " + dropped + " have no counterpart and are ignored";
    note(path, message + "; write that to say so");
    rewritten.value = entry;
    return true;
  }

  // The first board entry (no sensor_type) on each port.
  static std::map<std::string, std::size_t> arduino_boards(const json& drivers) {
    std::map<std::string, std::size_t> boards;
    for (std::size_t i = 0; i < drivers.size(); ++i)
      if (arduino_entry(drivers[i]) && !arduino_peripheral(drivers[i])) boards.emplace(drivers[i]["port"].get<std::string>(), i);
    return boards;
  }

  // A peripheral entry folded into its board's entry: an HC-SR04 becomes the board's `ultrasonic` block (the obstacle
  // stop); what the driver has no interface for is named and ignored.
  void fold_arduino_peripheral(const json& entry, const std::string& path, const std::string& named, NewEntry& board) {
    const json type = entry["sensor_type"];
    if (type == "hcsr04" && !board.value.contains("ultrasonic")) {
      json ultrasonic{{"sensor_type", type}};
      board.marks.emplace_back(path + ".sensor_type", ".ultrasonic.sensor_type");
      for (const char* key : {"trigger_pin", "echo_pin"})
        if (entry.contains(key)) {
          ultrasonic[key] = entry[key];
          board.marks.emplace_back(path + "." + key, std::string(".ultrasonic.") + key);
        }
      board.value["ultrasonic"] = std::move(ultrasonic);
      note(path, named + " (an HC-SR04 on the Arduino bridge of " + entry["port"].get<std::string>() +
                     ") is read as that board's `ultrasonic` block, the obstacle stop; write it there to say so");
      return;
    }
    note(path, named + " (sensor_type " + type.dump() + " on the Arduino bridge of " + entry["port"].get<std::string>() +
                   ") has no counterpart in rcand's arduino_serial_json driver and is ignored");
  }

  static bool pca9685_entry(const json& entry) {
    const auto protocol = entry.find("protocol");
    return protocol != entry.end() && protocol->is_string() &&
           (same_text(protocol->get_ref<const std::string&>(), "pca9685_i2c") ||
            same_text(protocol->get_ref<const std::string&>(), "pca9685"));
  }

  // The board a PCA9685 entry drives, {port, address} as written (the plugin's defaults where left out).
  static std::pair<std::string, std::string> pca9685_board(const json& entry) {
    const json port = entry.value("port", json("/dev/i2c-1"));
    json address = entry.value("address", json(64));
    if (address.is_string()) {
      try {
        address = std::stoi(address.get<std::string>(), nullptr, 0);
      } catch (const std::exception&) {
      }
    }
    char hex[16] = "";
    if (address.is_number_integer()) std::snprintf(hex, sizeof hex, "0x%02x", address.get<int>());
    return {port.is_string() ? port.get<std::string>() : port.dump(), *hex ? std::string(hex) : address.dump()};
  }

  // `channels` naming one channel per wheel ({left_front: 0, left_rear: 1, right_front: 2, right_rear: 3}), the
  // reference runtime's shape: its pca9685_i2c driver drives channels 0 and 1 as one DC motor's two inputs and 2 and 3
  // as the other's (castor/drivers/pca9685.py). Read as rcand's H-bridge per side, front input in1, rear in2.
  static bool per_wheel_channels(const json& entry) {
    const auto channels = entry.find("channels");
    if (!pca9685_entry(entry) || channels == entry.end() || !channels->is_object() || channels->size() != 4) return false;
    if (channels->contains("left") || channels->contains("right")) return false;
    int left = 0, right = 0;
    for (const auto& [name, channel] : channels->items()) {
      if (!channel.is_number_integer()) return false;
      const bool is_left = name.find("left") != std::string::npos, is_right = name.find("right") != std::string::npos;
      if (is_left == is_right) return false;
      (is_left ? left : right) += 1;
    }
    return left == 2 && right == 2;
  }

  // One side's two wheels as a motor {in1, in2, reverse?}: the front wheel's channel drives forward. `polarity` -1 on
  // both wheels of a side is a motor mounted backwards; wheels of one side that disagree cannot be one motor.
  static std::optional<json> side_motor(const json& entry, const std::string& side, const std::string& path,
                                        std::vector<std::pair<std::string, std::string>>& marks, std::string& problem) {
    std::vector<std::string> wheels;
    for (const auto& [name, channel] : entry["channels"].items())
      if (name.find(side) != std::string::npos) wheels.push_back(name);
    if (wheels[1].find("front") != std::string::npos && wheels[0].find("front") == std::string::npos)
      std::swap(wheels[0], wheels[1]);
    json motor = {{"in1", entry["channels"][wheels[0]]}, {"in2", entry["channels"][wheels[1]]}};
    marks.emplace_back(path + ".channels." + wheels[0], ".channels." + side + ".in1");
    marks.emplace_back(path + ".channels." + wheels[1], ".channels." + side + ".in2");
    const auto polarity = entry.find("polarity");
    if (polarity != entry.end() && polarity->is_object()) {
      const json first = polarity->value(wheels[0], json(1)), second = polarity->value(wheels[1], json(1));
      if (first != second) {
        problem += (problem.empty() ? "" : "; ") + std::string("polarity of ") + wheels[0] + " and " + wheels[1] + " differ";
        return std::nullopt;
      }
      if (first == -1) {
        motor["reverse"] = true;
        marks.emplace_back(path + ".polarity." + wheels[0], ".channels." + side + ".reverse");
      }
    }
    return motor;
  }

  // A PCA9685 entry whose channels name outputs that are no wheel motor ({pan: 8, tilt: 9}): servos.
  static bool pca9685_servo_entry(const json& entry) {
    const auto channels = entry.find("channels");
    if (channels == entry.end() || !channels->is_object() || channels->empty()) return false;
    for (const auto& [name, channel] : channels->items())
      if (!channel.is_number_integer() || name.find("left") != std::string::npos || name.find("right") != std::string::npos)
        return false;
    return true;
  }

  // The per-wheel entry rewritten as rcand's {channels: {left, right}, pwm_frequency_hz}; std::nullopt (and a
  // warning naming why) when its polarity says the two channels of a side are not one motor.
  std::optional<NewEntry> read_per_wheel_pca9685(const json& entry, const std::string& path, const std::string& named) {
    NewEntry rewritten{entry, {{path, ""}}};
    std::string problem;
    const auto left = side_motor(entry, "left", path, rewritten.marks, problem);
    const auto right = side_motor(entry, "right", path, rewritten.marks, problem);
    if (!left || !right) {
      note(path, named +
                     ": its channels name one PCA9685 channel per wheel, which rcand reads as one H-bridge per side, "
                     "but " +
                     problem + "; write channels: {left: {in1, in2}, right: {in1, in2}}");
      return std::nullopt;
    }
    json& value = rewritten.value;
    value["channels"] = {{"left", *left}, {"right", *right}};
    std::string message = named + ": channels " + entry["channels"].dump() +
                          " (one channel per wheel, the reference runtime's shape; its driver drives each side's two "
                          "channels as one DC motor's inputs) are read as channels " +
                          value["channels"].dump();
    if (value.contains("polarity")) {
      value.erase("polarity");
      message += " (polarity -1 on a side: reverse)";
    }
    if (value.contains("frequency") && !value.contains("pwm_frequency_hz")) {
      value["pwm_frequency_hz"] = value["frequency"];
      value.erase("frequency");
      rewritten.marks.emplace_back(path + ".frequency", ".pwm_frequency_hz");
      message += ", frequency as pwm_frequency_hz";
    }
    note(path, message + "; write that to say so");
    return rewritten;
  }

  void read_drivers() {
    const auto it = doc_.find("drivers");
    if (it == doc_.end() || !it->is_array()) return;
    const json drivers = *it;
    const auto boards = arduino_boards(drivers);
    std::map<std::size_t, std::size_t> board_slot;                 // board entry -> rewritten slot
    std::vector<std::pair<std::size_t, std::size_t>> peripherals;  // {entry, board entry}
    std::vector<NewEntry> rewritten;
    std::map<std::pair<std::string, std::string>, std::vector<std::size_t>> buses;    // {protocol, port} -> entries
    std::vector<std::pair<std::size_t, std::pair<std::string, std::string>>> bus_at;  // first entry -> bus
    std::map<std::pair<std::string, std::string>, std::string> pca9685_owners;        // {port, address} -> first entry
    bool changed = false;
    for (std::size_t i = 0; i < drivers.size(); ++i) {
      const json& entry = drivers[i];
      const std::string path = item("drivers", i);
      if (!entry.is_object()) {
        rewritten.push_back({entry, {{path, ""}}});
        continue;
      }
      const std::string id = entry.value("id", json("")).is_string() ? entry.value("id", std::string()) : std::string();
      const std::string named = id.empty() ? path : path + " (" + single_quoted(id) + ")";
      if (disabled(entry)) {
        note(path, named + " has enabled: false: not started (another runtime's switch)");
        changed = true;
        continue;
      }
      if (NewEntry bridge{entry, {{path, ""}}}; read_tb6612_gpio(bridge.value, path, named, bridge)) {
        changed = true;
        rewritten.push_back(std::move(bridge));
        continue;
      }
      if (json gpio = entry; read_gpio_shape(gpio, path, named)) {
        changed = true;
        if (!gpio.is_null()) rewritten.push_back({std::move(gpio), {{path, ""}}});
        continue;
      }
      if (const auto type = camera_protocol_type(entry)) {
        changed = true;
        const std::string protocol = entry["protocol"].get<std::string>();
        if (doc_.contains("camera")) {
          note(path, named + " (protocol " + single_quoted(protocol) +
                         ") is a camera; rcand serves one camera, the `camera` block's: this entry is ignored");
          continue;
        }
        std::string dropped;
        doc_["camera"] = camera_from(entry, path, entry.contains("url") && *type != "snapshot" ? "url" : *type, dropped);
        std::string message = named + " (protocol " + single_quoted(protocol) +
                              ") is a camera: read as rcand's `camera` block (plugin org.rcand.vision), not as a driver";
        if (!dropped.empty()) message += "; its keys " + dropped + " have no counterpart and are ignored";
        note(path, message + "; write `camera:` to say so");
        continue;
      }
      if (arduino_peripheral(entry)) {
        if (const auto board = boards.find(entry["port"].get<std::string>()); board != boards.end()) {
          changed = true;
          peripherals.emplace_back(i, board->second);
          continue;
        }
      }
      if (arduino_entry(entry) && boards.count(entry["port"].get<std::string>()) > 0 &&
          boards.at(entry["port"].get<std::string>()) == i) {
        board_slot[i] = rewritten.size();
        NewEntry board{entry, {{path, ""}}};
        drop_arduino_pins(board, named);
        if (board.value != entry) {
          changed = true;
          rewritten.push_back(std::move(board));
          continue;
        }
      }
      if (per_wheel_channels(entry))
        if (auto mapped = read_per_wheel_pca9685(entry, path, named)) {
          changed = true;
          pca9685_owners.emplace(pca9685_board(entry), named);
          rewritten.push_back(std::move(*mapped));
          continue;
        }
      if (pca9685_entry(entry)) {
        const auto board = pca9685_board(entry);
        const auto owner = pca9685_owners.find(board);
        if (owner != pca9685_owners.end() && pca9685_servo_entry(entry)) {
          changed = true;
          note(path, named + ": channels " + entry["channels"].dump() + " (servos) are other channels of the PCA9685 at " +
                         board.second + " on " + board.first + " that " + owner->second +
                         " drives: no conflict on the chip, but rcand's pca9685 driver owns its board's 16 channels as a "
                         "differential drive and has no servo outputs: this entry is ignored");
          continue;
        }
        pca9685_owners.emplace(board, named);
      }
      if (per_servo(entry)) {
        changed = true;
        const auto key = std::pair(entry["protocol"].get<std::string>(), entry["port"].get<std::string>());
        auto& members = buses[key];
        if (members.empty()) {
          bus_at.emplace_back(rewritten.size(), key);
          rewritten.push_back({});  // filled below, once every member is known
        }
        members.push_back(i);
        continue;
      }
      rewritten.push_back({entry, {{path, ""}}});
    }
    if (!changed) return;
    int bus_index = 0;
    for (const auto& [slot, key] : bus_at) rewritten[slot] = merge_servos(drivers, buses[key], bus_index++);
    for (const auto& [entry, board] : peripherals) {
      const std::string path = item("drivers", entry);
      const json& e = drivers[entry];
      const std::string id = e.value("id", json("")).is_string() ? e.value("id", std::string()) : std::string();
      const std::string named = id.empty() ? path : path + " (" + single_quoted(id) + ")";
      if (const auto slot = board_slot.find(board); slot != board_slot.end())
        fold_arduino_peripheral(e, path, named, rewritten[slot->second]);
      else note(path, named + " belongs to an Arduino bridge that is not started: ignored");
    }

    Marks old;
    copy_marks(marks_, old, "drivers", "drivers");
    for (auto mark = marks_.lower_bound("drivers["); mark != marks_.end() && mark->first.starts_with("drivers[");)
      mark = marks_.erase(mark);
    json list = json::array();
    for (std::size_t j = 0; j < rewritten.size(); ++j) {
      const std::string target = item("drivers", j);
      for (const auto& [from, to] : rewritten[j].marks) {
        if (to.empty()) copy_marks(old, marks_, from, target);  // the whole entry, as written
        else if (const auto mark = old.find(from); mark != old.end()) marks_[target + to] = mark->second;
      }
      list.push_back(std::move(rewritten[j].value));
    }
    doc_["drivers"] = std::move(list);
  }

  json& doc_;
  Marks& marks_;
  const std::string& file_;
  std::vector<ConfigDiagnostic>& notes_;
};

}  // namespace foreign_shapes_detail

void read_foreign_shapes(yaml::YamlDocument& document, const std::string& file, std::vector<yaml::ConfigDiagnostic>& notes) {
  foreign_shapes_detail::ShapeReader(document, file, notes).run();
}

}  // namespace rcand::config
