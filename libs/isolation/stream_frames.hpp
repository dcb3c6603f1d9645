// A body or a part of a stream on the channel: its place in the frame ring (frame_ring.hpp), or, for one too big for
// the ring, its bytes inline in the message.
#pragma once

#include <nlohmann/json.hpp>

#include "libs/isolation/frame_ring.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::isolation {

nlohmann::json encode_frame(FrameRing* ring, const sdk::SharedBytes& bytes);
// null: the frame is not there (see FrameRing::take) or the message is malformed.
sdk::SharedBytes decode_frame(FrameRing* ring, const nlohmann::json& frame);

}  // namespace rcand::isolation
