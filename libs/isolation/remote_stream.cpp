#include "libs/isolation/remote_stream.hpp"

#include <atomic>
#include <utility>
#include <vector>

#include "libs/isolation/stream_frames.hpp"

namespace rcand::isolation {

using nlohmann::json;

class RemoteStreams::Writer final : public sdk::StreamWriter {
 public:
  Writer(RemoteStreams& streams, std::uint64_t id) : streams_(streams), id_(id) {}
  // Dropped without an answer: rcand's writer, dropped in its turn, answers 500 as in process.
  ~Writer() override { send({{"t", "s_drop"}}); }

  bool start(int status, std::string content_type, sdk::Headers headers) noexcept override {
    if (closed_.load()) return false;
    try {
      return streams_.start(
          id_,
          {{"t", "s_start"}, {"v", id_}, {"status", status}, {"type", std::move(content_type)}, {"headers", std::move(headers)}});
    } catch (...) {  // a header that is not UTF-8
      return false;
    }
  }
  // The answer is complete after these (closed() turns true, as in rcand).
  bool send(sdk::SharedBytes body) noexcept override { return finish({{"t", "s_send"}, {"frame", frame(body)}}); }
  bool respond(const sdk::Response& response, sdk::Headers headers) noexcept override {
    return finish({{"t", "s_respond"}, {"status", response.status}, {"body", response.body}, {"headers", std::move(headers)}});
  }
  bool push(sdk::StreamPart part) noexcept override {
    return send({{"t", "s_push"},
                 {"frame", frame(part.data)},
                 {"type", std::move(part.content_type)},
                 {"headers", std::move(part.headers)}});
  }
  void end() noexcept override { finish({{"t", "s_end"}}); }
  bool closed() const noexcept override { return closed_.load(); }
  sdk::StreamCounters counters() const noexcept override {
    std::lock_guard lock(mutex_);
    return counters_;
  }

  void close() noexcept { closed_.store(true); }
  void set_counters(const sdk::StreamCounters& counters) {
    std::lock_guard lock(mutex_);
    counters_ = counters;
  }

 private:
  json frame(const sdk::SharedBytes& bytes) const { return encode_frame(streams_.ring_, bytes); }
  bool finish(json message) noexcept {
    const bool sent = send(std::move(message));
    closed_.store(true);
    return sent;
  }
  // Never waits: a stream whose rcand end is full skips a part, as a slow client's does.
  bool send(json message) noexcept {
    if (closed_.load()) return false;
    try {
      message["v"] = id_;
      return streams_.channel_.send(message, nullptr, /*wait=*/false);
    } catch (...) {  // a body that cannot be encoded (invalid UTF-8 in a JSON answer): the answer is lost, as a throw
      return false;
    }
  }

  RemoteStreams& streams_;
  const std::uint64_t id_;
  std::atomic<bool> closed_{false};
  mutable std::mutex mutex_;
  sdk::StreamCounters counters_;
};

std::shared_ptr<sdk::StreamWriter> RemoteStreams::open(std::uint64_t id) {
  auto writer = std::make_shared<Writer>(*this, id);
  std::lock_guard lock(mutex_);
  std::erase_if(writers_, [](const auto& entry) { return entry.second.expired(); });
  writers_[id] = writer;
  return writer;
}

void RemoteStreams::update(const json& state) {
  std::lock_guard lock(mutex_);
  for (const auto& id : state.at("closed")) {
    const auto it = writers_.find(id.get<std::uint64_t>());
    if (it == writers_.end()) continue;
    if (auto writer = it->second.lock()) writer->close();
    writers_.erase(it);
  }
  for (const auto& entry : state.at("counters"))
    if (const auto it = writers_.find(entry.at(0).get<std::uint64_t>()); it != writers_.end())
      if (auto writer = it->second.lock())
        writer->set_counters(
            {entry.at(1).get<std::uint64_t>(), entry.at(2).get<std::uint64_t>(), entry.at(3).get<std::uint64_t>()});
}

void RemoteStreams::close_all() {
  {
    std::lock_guard lock(mutex_);
    ended_ = true;
    for (auto& [id, weak] : writers_)
      if (auto writer = weak.lock()) writer->close();
    writers_.clear();
  }
  answered_.notify_all();
}

bool RemoteStreams::start(std::uint64_t id, const json& message) {
  std::unique_lock lock(mutex_);
  if (ended_ || starts_.contains(id)) return false;
  starts_[id];
  lock.unlock();
  const bool sent = channel_.send(message, nullptr, /*wait=*/false);
  lock.lock();
  // rcand's reader answers at once; the bound is only against a channel that ends without a word.
  if (sent) answered_.wait_for(lock, kStartAnswer, [&] { return starts_[id].has_value() || ended_; });
  const bool started = starts_[id].value_or(false);
  starts_.erase(id);
  return started;
}

void RemoteStreams::started(const json& answer) {
  {
    std::lock_guard lock(mutex_);
    if (const auto it = starts_.find(answer.at("v").get<std::uint64_t>()); it != starts_.end())
      it->second = answer.at("ok").get<bool>();
  }
  answered_.notify_all();
}

}  // namespace rcand::isolation
