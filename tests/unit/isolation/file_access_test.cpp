// Which entries of /dev an isolated capability's process may open (libs/isolation/file_access.hpp): the ordinary
// ones always, cameras with "video", serial ports and pseudo-terminals with "serial", and never a bus, memory, input
// or a console, which belong to rcand's drivers or to nobody.
#include <doctest/doctest.h>

#include "libs/isolation/file_access.hpp"

using rcand::isolation::device_allowed;
using rcand::isolation::FileNeeds;

TEST_CASE("device access: each entry of /dev by what the manifest entry needs") {
  struct Row {
    const char* name;
    bool without_needs, with_video, with_serial;
  };
  const Row rows[] = {
      {"null", true, true, true},          {"zero", true, true, true},       {"urandom", true, true, true},
      {"shm", true, true, true},           {"video0", false, true, false},   {"media1", false, true, false},
      {"v4l-subdev2", false, true, false}, {"v4l", false, true, false},      {"dma_heap", false, true, false},
      {"ttyUSB0", false, false, true},     {"ttyACM1", false, false, true},  {"ttyS0", false, false, true},
      {"ttyAMA0", false, false, true},     {"serial", false, false, true},   {"pts", false, false, true},
      {"ptmx", false, false, true},        {"tty", false, false, false},     {"tty1", false, false, false},
      {"gpiochip0", false, false, false},  {"i2c-1", false, false, false},   {"spidev0.0", false, false, false},
      {"mem", false, false, false},        {"input", false, false, false},   {"uinput", false, false, false},
      {"hidraw0", false, false, false},    {"nvme0n1", false, false, false}, {"kmsg", false, false, false},
  };
  const FileNeeds none, video{true, false, {}}, serial{false, true, {}};
  for (const auto& row : rows) {
    CAPTURE(row.name);
    CHECK(device_allowed(row.name, none) == row.without_needs);
    CHECK(device_allowed(row.name, video) == row.with_video);
    CHECK(device_allowed(row.name, serial) == row.with_serial);
  }
}
