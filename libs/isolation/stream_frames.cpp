#include "libs/isolation/stream_frames.hpp"

namespace rcand::isolation {

using nlohmann::json;

json encode_frame(FrameRing* ring, const sdk::SharedBytes& bytes) {
  if (!bytes) return json::binary({});
  if (ring != nullptr)
    if (const auto slot = ring->put(bytes)) return {slot->at, slot->length};
  return json::binary(json::binary_t::container_type(bytes->begin(), bytes->end()));
}

sdk::SharedBytes decode_frame(FrameRing* ring, const json& frame) {
  if (frame.is_binary()) return std::make_shared<const std::string>(frame.get_binary().begin(), frame.get_binary().end());
  if (ring == nullptr || !frame.is_array() || frame.size() != 2 || !frame[0].is_number_unsigned() ||
      !frame[1].is_number_unsigned() || frame[1].get<std::uint64_t>() > UINT32_MAX)
    return nullptr;
  return ring->take({frame[0].get<std::uint64_t>(), frame[1].get<std::uint32_t>()});
}

}  // namespace rcand::isolation
