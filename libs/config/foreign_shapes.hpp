// The shapes another runtime (the reference runtime, craigm26/OpenCastor) writes for what rcand has a concept for,
// read as rcand's own before the file is validated, each reading named once in a warning:
// - `cameras:` (a mapping of named cameras or a list) becomes the `camera` block: the one with role primary, else the
//   one named main, else the first;
// - drivers[] entries that are cameras (v4l2, picamera, picam, usb_camera, mjpeg_stream, http) become the `camera`
//   block when there is none, and leave the drivers;
// - per-servo drivers[] entries (hardware_id, link_id) of one protocol on one port become one bus entry with
//   `servos: [{id, joint, min_deg, max_deg}]` (the joint from link_id, the limits from that link's limits_deg);
// - a drivers[] entry with `enabled: false` is not started;
// - pca9685_i2c `channels` named per wheel are one H-bridge per side; a second entry on that board with servo channels
//   is ignored; an Arduino bridge's pins in the reference runtime's shapes are its firmware's, ignored;
// - a `gpio` TB6612 written {ain1_gpio, ..., standby_gpio} is the gpio driver's channels and standby; `gpio` entries
//   that are the SunFounder Robot HAT or an HC-SR04 become those protocols, other gpio sensors are
//   ignored; camera.type oakd becomes a driver of protocol oakd; `teleop` listed for an arm is taken out.
// The source marks move with the keys, so every later diagnostic points at what the file says.
#pragma once

#include <string>
#include <vector>

#include "libs/yaml/diagnostic.hpp"
#include "libs/yaml/yaml_document.hpp"

namespace rcand::config {

void read_foreign_shapes(yaml::YamlDocument& document, const std::string& file, std::vector<yaml::ConfigDiagnostic>& notes);

}  // namespace rcand::config
