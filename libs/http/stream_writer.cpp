#include "libs/http/stream_writer.hpp"

#include <rcand/sdk/contract/requests.hpp>

#include <mutex>
#include <utility>

#include "libs/http/response_stream.hpp"

namespace rcand::http {
namespace {

bool safe_header_text(std::string_view text) noexcept {
  return text.find_first_of(std::string_view{"\r\n\0", 3}) == std::string_view::npos;
}

class PluginStreamWriter final : public sdk::StreamWriter {
 public:
  explicit PluginStreamWriter(FirstAnswer answer) : answer_(std::move(answer)) {}

  ~PluginStreamWriter() override {
    std::lock_guard lock(mutex_);
    if (state_ == State::Streaming) stream_->end();
    else if (state_ != State::Done) {
      try {
        answer_locked(error_response(500, "INTERNAL", "the stream handler dropped the request without an answer"));
      } catch (...) {  // out of memory: the server's own unanswered-request path answers
      }
    }
  }

  bool start(int status, std::string content_type, sdk::Headers headers) noexcept override try {
    std::lock_guard lock(mutex_);
    if (state_ != State::Idle) return false;
    if (!content_type.starts_with("multipart/")) {
      pending_ = Response{status, std::move(content_type), {}, std::move(headers), nullptr};
      state_ = State::Started;
      return true;
    }
    auto stream = std::make_shared<ResponseStream>();
    Response head{status, content_type + "; boundary=" + std::string(kStreamBoundary), {}, std::move(headers), stream};
    head.headers.emplace_back("Cache-Control", "no-store");
    if (!answer_locked(std::move(head))) return false;
    stream_ = std::move(stream);
    state_ = State::Streaming;
    return true;
  } catch (...) {
    return false;
  }

  bool send(sdk::SharedBytes body) noexcept override try {
    std::lock_guard lock(mutex_);
    if (state_ != State::Started) return false;
    if (body) pending_.body = *body;
    sent_bytes_ = pending_.body.size();
    return answer_locked(std::move(pending_));
  } catch (...) {
    return false;
  }

  bool respond(const sdk::Response& response, sdk::Headers headers) noexcept override try {
    std::lock_guard lock(mutex_);
    if (state_ != State::Idle) return false;
    const sdk::Response shaped = sdk::contract::normalized(response);
    Response answer{shaped.status, "application/json", shaped.body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                    std::move(headers), nullptr};
    sent_bytes_ = answer.body.size();
    return answer_locked(std::move(answer));
  } catch (...) {
    return false;
  }

  bool push(sdk::StreamPart part) noexcept override try {
    std::shared_ptr<ResponseStream> stream;
    {
      std::lock_guard lock(mutex_);
      if (state_ != State::Streaming) return false;
      stream = stream_;
    }
    std::string head = "--" + std::string(kStreamBoundary) + "\r\nContent-Type: " + part.content_type +
                       "\r\nContent-Length: " + std::to_string(part.data ? part.data->size() : 0) + "\r\n";
    for (const auto& [name, value] : part.headers)
      if (!name.empty() && safe_header_text(name) && safe_header_text(value) && name.find(':') == std::string::npos)
        head += name + ": " + value + "\r\n";
    head += "\r\n";
    return stream->push({std::move(head), std::move(part.data), "\r\n"});
  } catch (...) {
    return false;
  }

  void end() noexcept override {
    std::lock_guard lock(mutex_);
    if (state_ == State::Streaming) stream_->end();
  }

  bool closed() const noexcept override {
    std::lock_guard lock(mutex_);
    if (state_ == State::Streaming) return stream_->closed();
    return state_ == State::Done;
  }

  sdk::StreamCounters counters() const noexcept override {
    std::lock_guard lock(mutex_);
    if (stream_) {
      const auto c = stream_->counters();
      return {c.sent, c.dropped, c.bytes};
    }
    return state_ == State::Done && answered_ ? sdk::StreamCounters{1, 0, sent_bytes_} : sdk::StreamCounters{};
  }

 private:
  enum class State { Idle, Started, Streaming, Done };

  // The one answer. A stream stays Streaming when accepted; everything else is Done.
  bool answer_locked(Response response) {
    const bool streamed = response.stream != nullptr;
    answered_ = answer_(std::move(response));
    if (!answered_ || !streamed) state_ = State::Done;
    return answered_;
  }

  mutable std::mutex mutex_;
  FirstAnswer answer_;
  State state_ = State::Idle;
  Response pending_;  // start() of a whole body, waiting for send()
  std::shared_ptr<ResponseStream> stream_;
  std::uint64_t sent_bytes_ = 0;
  bool answered_ = false;
};

}  // namespace

std::shared_ptr<sdk::StreamWriter> make_stream_writer(FirstAnswer answer) {
  return std::make_shared<PluginStreamWriter>(std::move(answer));
}

}  // namespace rcand::http
