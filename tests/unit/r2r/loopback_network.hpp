// An in-memory R2R network for unit tests: each robot gets a Transport endpoint; sent messages wait in one queue
// until the test calls pump(), so every exchange is deterministic and no thread runs.
#pragma once

#include <deque>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "services/r2r/transport.hpp"

namespace r2r_test {

using rcand::services::r2r::Deliver;
using rcand::services::r2r::InboundMessage;
using rcand::services::r2r::Transport;

class LoopbackNetwork {
 public:
  struct Sent {
    std::string from;
    std::optional<std::string> to;  // nullopt: broadcast
    nlohmann::json message;
  };

  class Endpoint final : public Transport {
   public:
    Endpoint(LoopbackNetwork& net, std::string name) : net_(net), name_(std::move(name)) {}
    std::string_view name() const noexcept override { return "local"; }
    void start(Deliver deliver) override { deliver_ = std::move(deliver); }
    bool send(const std::string& bytes, const std::optional<std::string>& target) override {
      if (target && !net_.endpoints_.contains(*target)) return false;
      net_.log.push_back({name_, target, nlohmann::json::parse(bytes)});
      if (!muted) net_.queue_.push_back({name_, target, bytes});
      return true;
    }
    void stop() noexcept override { deliver_ = nullptr; }
    bool muted = false;  // a robot gone silent: what it sends never arrives

   private:
    friend class LoopbackNetwork;
    LoopbackNetwork& net_;
    std::string name_;
    Deliver deliver_;
  };

  Endpoint& endpoint(const std::string& robot) {
    auto& slot = endpoints_[robot];
    if (!slot) slot = std::make_unique<Endpoint>(*this, robot);
    return *slot;
  }

  // Delivers queued messages (and those they cause) until the network is quiet. Returns how many were delivered.
  int pump(int limit = 10000) {
    int delivered = 0;
    while (!queue_.empty() && delivered < limit) {
      Queued q = std::move(queue_.front());
      queue_.pop_front();
      for (auto& [name, endpoint] : endpoints_) {
        if (name == q.from || (q.to && *q.to != name) || !endpoint->deliver_) continue;
        endpoint->deliver_(inbound(q.bytes, q.from, name));
        ++delivered;
      }
    }
    return delivered;
  }

  // Hands raw bytes to `robot` as if `from` had sent them; its direct replies are collected in `replies`.
  void inject(const std::string& robot, const std::string& bytes, std::vector<nlohmann::json>* replies = nullptr) {
    InboundMessage message;
    message.bytes = bytes;
    message.transport = "local";
    message.peer = "test";
    if (replies) message.reply = [replies](std::string answer) { replies->push_back(nlohmann::json::parse(answer)); };
    endpoint(robot).deliver_(std::move(message));
  }

  // Every message of `type` sent so far (optionally only from / to someone).
  std::vector<Sent> sent(const std::string& type, std::optional<std::string> from = std::nullopt,
                         std::optional<std::string> to = std::nullopt) const {
    std::vector<Sent> out;
    for (const Sent& s : log)
      if (s.message["type"] == type && (!from || s.from == *from) && (!to || s.message["header"].value("target_id", "") == *to))
        out.push_back(s);
    return out;
  }

  std::vector<Sent> log;

 private:
  struct Queued {
    std::string from;
    std::optional<std::string> to;
    std::string bytes;
  };
  // `replier` answers `from` on the same "connection"; a muted replier's answers are lost too.
  InboundMessage inbound(const std::string& bytes, const std::string& from, const std::string& replier) {
    InboundMessage message;
    message.bytes = bytes;
    message.transport = "local";
    message.peer = from;
    message.reply = [this, from, replier](std::string answer) {
      log.push_back({replier, from, nlohmann::json::parse(answer)});
      if (!endpoints_.at(replier)->muted) queue_.push_back({replier, from, std::move(answer)});
    };
    return message;
  }
  std::map<std::string, std::unique_ptr<Endpoint>> endpoints_;
  std::deque<Queued> queue_;
};

}  // namespace r2r_test
