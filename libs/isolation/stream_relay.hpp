// rcand's side of an isolated capability's stream routes: each client's StreamWriter (the kernel's) kept under an id
// while the host's plugin writes to it through messages (remote_stream.hpp). The host is not trusted: a message for
// an id rcand did not give, or one that does not decode, reaches no client.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "libs/isolation/frame_ring.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::isolation {

class StreamRelay {
 public:
  // A client's writer, kept until the host ends, drops or answers it, or the client leaves: its id for the host.
  std::uint64_t open(std::shared_ptr<sdk::StreamWriter> writer);
  // One of the host's "s_*" messages, carried out on the client's writer (frames from `ring`), and the answer the host
  // waits for (to "s_start": {"t":"s_started","v","ok"}). Throws nlohmann's exception for a message that does not
  // decode.
  std::optional<nlohmann::json> deliver(const nlohmann::json& message, FrameRing* ring);
  // For the heartbeat: {"t":"s_state","closed":[ids of clients gone],"counters":[[id,sent,dropped,bytes]...]}, the
  // gone ones forgotten; nullopt when there are no streams.
  std::optional<nlohmann::json> state();
  // The host ended: clients not answered yet get `unavailable`, the others' streams end.
  void end_all(const sdk::Response& unavailable);

 private:
  std::mutex mutex_;
  std::uint64_t next_id_ = 0;
  std::map<std::uint64_t, std::shared_ptr<sdk::StreamWriter>> writers_;
};

}  // namespace rcand::isolation
