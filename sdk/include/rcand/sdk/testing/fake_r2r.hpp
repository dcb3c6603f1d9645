// R2R for the fake host (rcand/sdk/testing/fake_host.hpp): the R2rLinks service a plugin finds with
// find<R2rLinks>(ctx), links that record what they send instead of signing it onto a wire, and delivery of a test's
// message to the subscriptions of its type, each on its subscriber's worker as the kernel does. Usable alone: a test
// of a plugin part that takes an R2rLinks can hand it a FakeR2r.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk::testing {

class FakeR2r final : public R2rLinks {
 public:
  struct Sent {
    std::string instance;  // who sent it: the `who` of R2rLinks::make_link (the instance id for PluginContext::r2r())
    std::string type;
    nlohmann::json payload;
    std::optional<std::string> target;
  };

  FakeR2r() = default;
  FakeR2r(const FakeR2r&) = delete;
  FakeR2r& operator=(const FakeR2r&) = delete;

  std::unique_ptr<R2rLink> make_link(Worker& worker, std::string_view who) const noexcept override {
    try {
      // (const to the plugins that find it, as every service; its links record into it)
      return std::make_unique<Link>(const_cast<FakeR2r&>(*this), worker, std::string(who));
    } catch (...) {
      return nullptr;
    }
  }

  // What links sent, in order. The fake checks the type and that the payload is an object; the kernel also checks
  // each type's payload fields (docs/protocol.md §11). Read it from the test's thread while no plugin sends.
  const std::vector<Sent>& sent() const noexcept { return sent_; }
  // Queues `message` for every subscription of its type on the subscriber's worker, as the kernel does for a
  // validated message. Returns how many subscriptions it was queued for.
  std::size_t deliver(const R2rMessage& message) {
    std::lock_guard lock(mutex_);
    std::size_t queued = 0;
    for (const auto& [id, sub] : subscriptions_) {
      if (sub.type != message.type) continue;
      sub.worker->post([callback = sub.callback, message] { callback(message); });
      ++queued;
    }
    return queued;
  }
  // The cost function a link installed (empty: the kernel's default).
  R2rCostFunction cost_function() const {
    std::lock_guard lock(mutex_);
    return cost_;
  }
  // Later sends fail with `error` ("R2R is not running on this robot"); an empty string makes them succeed again.
  void fail_sends(std::string error) {
    std::lock_guard lock(mutex_);
    send_error_ = std::move(error);
  }

 private:
  class Link final : public R2rLink {
   public:
    Link(FakeR2r& r2r, Worker& worker, std::string who) : r2r_(r2r), worker_(worker), instance_(std::move(who)) {}
    ~Link() override {
      std::lock_guard lock(r2r_.mutex_);
      std::erase_if(r2r_.subscriptions_, [this](const auto& entry) { return entry.second.link == this; });
    }
    R2rSendResult send(std::string_view type, const Json& payload, const std::optional<std::string>& target) override {
      if (!known(type)) return {false, "unknown R2R message type '" + std::string(type) + "'", "/type"};
      if (!payload.is_object()) return {false, "payload must be an object", "/payload"};
      std::lock_guard lock(r2r_.mutex_);
      if (!r2r_.send_error_.empty()) return {false, r2r_.send_error_, ""};
      r2r_.sent_.push_back({instance_, std::string(type), payload, target});
      return {true, "", ""};
    }
    std::uint64_t subscribe(std::string_view type, Callback callback) override {
      if (!known(type)) throw std::invalid_argument("unknown R2R message type '" + std::string(type) + "'");
      if (!callback) throw std::invalid_argument("R2R subscribe needs a callback");
      std::lock_guard lock(r2r_.mutex_);
      const std::uint64_t id = ++r2r_.next_id_;
      r2r_.subscriptions_[id] = {this, &worker_, std::string(type), std::move(callback)};
      return id;
    }
    void unsubscribe(std::uint64_t id) noexcept override {
      std::lock_guard lock(r2r_.mutex_);
      r2r_.subscriptions_.erase(id);
    }
    void set_cost_function(R2rCostFunction cost) override {
      std::lock_guard lock(r2r_.mutex_);
      r2r_.cost_ = std::move(cost);
    }

   private:
    static bool known(std::string_view type) {
      for (std::string_view t : {"status", "task_request", "task_response", "command", "negotiation", "error"})
        if (t == type) return true;
      return false;
    }
    FakeR2r& r2r_;
    Worker& worker_;
    std::string instance_;
  };

  struct Subscription {
    const Link* link;
    Worker* worker;  // the link's: where its callbacks run
    std::string type;
    R2rLink::Callback callback;
  };

  mutable std::mutex mutex_;  // links send and subscribe from their plugins' threads
  std::vector<Sent> sent_;
  std::map<std::uint64_t, Subscription> subscriptions_;
  std::uint64_t next_id_ = 0;
  R2rCostFunction cost_;
  std::string send_error_;
};

}  // namespace rcand::sdk::testing
