// The stream-route fixtures (tests/unit/plugin_host/stream_routes_test.cpp): one capability class, built into a
// plugin that declares the kernel's minor (its stream routes are served) and one that declares minor 1 (the kernel
// must never call stream_routes() on it: a real 1.1 plugin has no such slot in its vtable, and this one throws there
// to show it was called).
#pragma once

#include <thread>

#include "../fixture.hpp"

namespace rcand::test {

class StreamingCapability final : public sdk::Capability {
 public:
  explicit StreamingCapability(bool throw_in_stream_routes) : throw_(throw_in_stream_routes) {}
  std::vector<sdk::Route> routes() override {
    return {get_route("/ping", [](const sdk::Request&) { return sdk::Response::ok({{"ok", true}}); })};
  }
  std::vector<sdk::StreamRoute> stream_routes() override {
    if (throw_) throw std::logic_error("stream_routes() called on a plugin that declared ABI minor 1");
    auto route = [](std::string path, std::function<void(const sdk::Request&, std::shared_ptr<sdk::StreamWriter>)> handler) {
      return sdk::StreamRoute{"GET", std::move(path), sdk::Scope::Status, std::move(handler)};
    };
    return {
        // One whole body.
        route("/bytes",
              [](const sdk::Request&, std::shared_ptr<sdk::StreamWriter> writer) {
                if (writer->start(200, "application/octet-stream", {{"X-Fixture", "1"}}))
                  writer->send(std::make_shared<const std::string>("stream-ok"));
              }),
        // Three parts from another thread, after the handler returned, then the end.
        route("/parts",
              [](const sdk::Request&, std::shared_ptr<sdk::StreamWriter> writer) {
                writer->start(200, "multipart/x-mixed-replace");
                std::thread([writer] {
                  for (int i = 1; i <= 3; ++i)
                    writer->push({std::make_shared<const std::string>("part-" + std::to_string(i)), "text/plain", {}});
                  writer->end();
                }).detach();
              }),
        // A JSON refusal with a header.
        route("/refuse",
              [](const sdk::Request&, std::shared_ptr<sdk::StreamWriter> writer) {
                writer->respond(sdk::Response::error(503, "UNAVAILABLE", "full", {{"limit", 1}}), {{"Retry-After", "5"}});
              }),
        // Keeps the writer and never answers: the client gets 503 at the handler timeout, the capability stays up.
        route("/silent",
              [this](const sdk::Request&, std::shared_ptr<sdk::StreamWriter> writer) { kept_.push_back(std::move(writer)); }),
        // Drops the writer unanswered: 500.
        route("/drop", [](const sdk::Request&, std::shared_ptr<sdk::StreamWriter>) {}),
        // Throws: 500, and the capability is failed.
        route("/throw", [](const sdk::Request&, std::shared_ptr<sdk::StreamWriter>) { throw std::runtime_error("boom"); }),
    };
  }

 private:
  bool throw_;
  std::vector<std::shared_ptr<sdk::StreamWriter>> kept_;  // only touched on the capability's worker
};

}  // namespace rcand::test
