#include "libs/config/foreign_shapes.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <map>
#include <optional>
#include <string_view>
#include <utility>

namespace rcand::kernel {
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

  // The reference runtime's names of the Raspberry Pi camera (a V4L2 device through libcamera) as camera.type.
  void read_camera_type() {
    const auto camera = doc_.find("camera");
    if (camera == doc_.end() || !camera->is_object()) return;
    const auto type = camera->find("type");
    if (type == camera->end() || !type->is_string()) return;
    const std::string written = type->get<std::string>();
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
          boards.at(entry["port"].get<std::string>()) == i)
        board_slot[i] = rewritten.size();
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

}  // namespace rcand::kernel
