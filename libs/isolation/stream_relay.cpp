#include "libs/isolation/stream_relay.hpp"

#include <utility>

#include "libs/isolation/stream_frames.hpp"

namespace rcand::isolation {

using nlohmann::json;

std::uint64_t StreamRelay::open(std::shared_ptr<sdk::StreamWriter> writer) {
  std::lock_guard lock(mutex_);
  writers_[++next_id_] = std::move(writer);
  return next_id_;
}

std::optional<json> StreamRelay::deliver(const json& message, FrameRing* ring) {
  const std::string type = message.at("t").get<std::string>();
  const auto id = message.at("v").get<std::uint64_t>();
  std::shared_ptr<sdk::StreamWriter> writer;
  {
    std::lock_guard lock(mutex_);
    const auto it = writers_.find(id);
    if (it == writers_.end()) {  // a client gone, or an id rcand never gave
      if (type == "s_start") return json{{"t", "s_started"}, {"v", id}, {"ok", false}};
      return std::nullopt;
    }
    writer = it->second;
    if (type != "s_start" && type != "s_push") writers_.erase(it);  // the answer is complete, or the plugin let go
  }
  if (type == "s_start") {
    const bool ok = writer->start(message.at("status").get<int>(), message.at("type").get<std::string>(),
                                  message.at("headers").get<sdk::Headers>());
    return json{{"t", "s_started"}, {"v", id}, {"ok", ok}};
  }
  if (type == "s_push") {
    if (auto bytes = decode_frame(ring, message.at("frame")))
      writer->push({std::move(bytes), message.at("type").get<std::string>(), message.at("headers").get<sdk::Headers>()});
  } else if (type == "s_send") {
    // A body written over before rcand read it is not sent: the writer, dropped here, cuts the answer, never sends a
    // wrong one.
    if (auto bytes = decode_frame(ring, message.at("frame"))) writer->send(std::move(bytes));
  } else if (type == "s_respond") {
    writer->respond({message.at("status").get<int>(), message.at("body")}, message.at("headers").get<sdk::Headers>());
  } else if (type == "s_end") {
    writer->end();
  }  // "s_drop": the plugin let go unanswered; rcand's writer, dropped here, answers 500 or ends its stream
  return std::nullopt;
}

std::optional<json> StreamRelay::state() {
  std::lock_guard lock(mutex_);
  if (writers_.empty()) return std::nullopt;
  json state{{"t", "s_state"}, {"closed", json::array()}, {"counters", json::array()}};
  for (auto it = writers_.begin(); it != writers_.end();) {
    if (it->second->closed()) {
      state["closed"].push_back(it->first);
      it = writers_.erase(it);
      continue;
    }
    const auto counters = it->second->counters();
    state["counters"].push_back({it->first, counters.sent, counters.dropped, counters.bytes});
    ++it;
  }
  return state;
}

void StreamRelay::end_all(const sdk::Response& unavailable) {
  std::map<std::uint64_t, std::shared_ptr<sdk::StreamWriter>> writers;
  {
    std::lock_guard lock(mutex_);
    writers.swap(writers_);
  }
  for (auto& [id, writer] : writers)
    if (!writer->respond(unavailable)) writer->end();
}

}  // namespace rcand::isolation
