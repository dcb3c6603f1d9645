// A StreamWriter for plugin tests (rcand/sdk/stream.hpp) that keeps the host's rules: one answer, multipart parts
// only after a multipart start(), and AT MOST ONE pending part - a part pushed while the previous one is unread
// replaces it and counts as dropped. The test plays the client: a reading client (the default) takes every part at
// once; a stalled one takes nothing until take() or close_client(). Thread-safe; waits are bounded.
//
//   auto viewer = std::make_shared<RecordingStream>();
//   route.handler(request, viewer);                       // a StreamRoute from Capability::stream_routes()
//   REQUIRE(viewer->wait_for_parts(3, std::chrono::seconds(2)));
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "rcand/sdk/contract/requests.hpp"
#include "rcand/sdk/stream.hpp"

namespace rcand::sdk::testing {

class RecordingStream final : public StreamWriter {
 public:
  enum class Client { Reads, Stalled };
  explicit RecordingStream(Client client = Client::Reads) : reads_(client == Client::Reads) {}

  // ---- StreamWriter ----
  bool start(int status, std::string content_type, Headers headers) noexcept override {
    std::lock_guard lock(mutex_);
    if (answered_ || gone_) return false;
    status_ = status;
    content_type_ = std::move(content_type);
    headers_ = std::move(headers);
    multipart_ = content_type_.rfind("multipart/", 0) == 0;
    answered_ = true;
    changed_.notify_all();
    return true;
  }
  bool send(SharedBytes body) noexcept override {
    std::lock_guard lock(mutex_);
    if (!answered_ || multipart_ || complete_ || gone_) return false;
    body_ = body ? *body : std::string();
    complete_ = true;
    counters_ = {1, 0, body_.size()};
    changed_.notify_all();
    return true;
  }
  bool respond(const Response& response, Headers headers) noexcept override {
    std::lock_guard lock(mutex_);
    if (answered_ || gone_) return false;
    const Response shaped = contract::normalized(response);
    status_ = shaped.status;
    json_ = shaped.body;
    content_type_ = "application/json";
    headers_ = std::move(headers);
    answered_ = complete_ = true;
    changed_.notify_all();
    return true;
  }
  bool push(StreamPart part) noexcept override {
    std::lock_guard lock(mutex_);
    if (!multipart_ || ended_ || gone_) return false;
    if (reads_) {
      deliver(std::move(part));
    } else {
      if (pending_) ++counters_.dropped;
      pending_ = std::move(part);
    }
    changed_.notify_all();
    return true;
  }
  void end() noexcept override {
    std::lock_guard lock(mutex_);
    ended_ = true;
    changed_.notify_all();
  }
  bool closed() const noexcept override {
    std::lock_guard lock(mutex_);
    return gone_ || complete_ || (ended_ && !pending_);
  }
  StreamCounters counters() const noexcept override {
    std::lock_guard lock(mutex_);
    return counters_;
  }

  // ---- the client ----
  // A stalled client reads the pending part, if any.
  void take() {
    std::lock_guard lock(mutex_);
    if (pending_) deliver(std::move(*pending_));
    pending_.reset();
    changed_.notify_all();
  }
  // The client leaves: closed() turns true and later pushes are refused.
  void close_client() {
    std::lock_guard lock(mutex_);
    gone_ = true;
    pending_.reset();
    changed_.notify_all();
  }

  // ---- what the client got ----
  std::optional<int> status() const {
    return locked([&] { return status_; });
  }
  std::string content_type() const {
    return locked([&] { return content_type_; });
  }
  Headers headers() const {
    return locked([&] { return headers_; });
  }
  std::string body() const {
    return locked([&] { return body_; });
  }  // send()'s body
  Json json() const {
    return locked([&] { return json_; });
  }  // respond()'s body
  std::vector<StreamPart> parts() const {
    return locked([&] { return parts_; });
  }  // read, in order
  bool has_pending() const {
    return locked([&] { return pending_.has_value(); });
  }
  bool answered() const {
    return locked([&] { return answered_; });
  }

  // Bounded waits (true: it happened).
  bool wait_for_parts(std::size_t count, std::chrono::milliseconds limit) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return parts_.size() >= count; });
  }
  bool wait_for_answer(std::chrono::milliseconds limit) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return answered_ && (multipart_ || complete_); });
  }
  template <class Pred> bool wait_until(Pred done, std::chrono::milliseconds limit) const {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return done(parts_); });
  }

 private:
  void deliver(StreamPart part) {
    ++counters_.sent;
    counters_.bytes += part.data ? part.data->size() : 0;
    parts_.push_back(std::move(part));
  }
  template <class F> std::invoke_result_t<F> locked(F f) const {
    std::lock_guard lock(mutex_);
    return f();
  }

  const bool reads_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::optional<int> status_;
  std::string content_type_, body_;
  Json json_;
  Headers headers_;
  std::vector<StreamPart> parts_;
  std::optional<StreamPart> pending_;
  StreamCounters counters_;
  bool answered_ = false, multipart_ = false, complete_ = false, ended_ = false, gone_ = false;
};

}  // namespace rcand::sdk::testing
