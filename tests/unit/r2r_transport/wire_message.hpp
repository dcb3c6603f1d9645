// An R2R message as the transports carry it (they peek at the header only), for the transport tests.
#pragma once

#include <cstddef>
#include <string>

#include <nlohmann/json.hpp>

namespace rcand::test {

// A message of `type` from `source`; `padding` bytes in the payload make it as large as a test needs.
inline std::string wire_message(const std::string& type, const std::string& source = "a", std::size_t padding = 0) {
  const nlohmann::json payload = padding ? nlohmann::json{{"pad", std::string(padding, 'x')}} : nlohmann::json::object();
  return nlohmann::json{{"header", {{"version", "1.0"}, {"timestamp", 1}, {"source_id", source}}},
                        {"type", type},
                        {"payload", payload}}
      .dump();
}

}  // namespace rcand::test
