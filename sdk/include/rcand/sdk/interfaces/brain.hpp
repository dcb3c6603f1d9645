// Brains (RCAN §9 chat): what turns an English instruction into a proposed robot command. The chat capability
// (org.rcand.chat) owns everything around a brain - input limits, the prompt-injection scan (one scanner for every
// brain, run before any brain is asked), validation of the proposal against the declared capabilities and their
// bounds, the confidence gate, the e-stop epoch, and the dispatch as the caller through RequestDispatcher. A brain
// only proposes: it never dispatches, never reaches a driver, and chat checks its answer as if it were hostile.
//
// A vendor brain is a plugin that offers its Brain under brain_service_id("<provider>") (rcand/sdk/services.hpp);
// chat finds it by the robot config's agent.provider. chat's own brains: the embedded grammar brain ("grammar"), and
// the HTTP brains - OpenAI-compatible and Ollama - named "openai", "ollama" or under runtime.capabilities.chat.brains,
// which chat offers as Brain services under their names too (another plugin can ask the robot's configured model).
//
// Unlike other services, propose() blocks for as long as the brain thinks (up to the request's deadline): call it
// only from a worker of your own, never from a handler, a kernel thread or a stop path.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"

namespace rcand::sdk {

// Cancels one brain call: an e-stop, shutdown, or the deadline. Copies share one state (so const copies can cancel
// too). Any thread, never blocks beyond a brief lock.
class CancelToken {
 public:
  CancelToken() : state_(std::make_shared<State>()) {}
  bool cancelled() const noexcept { return state_->cancelled.load(); }
  // Runs `callback` once on cancellation, on the cancelling thread (at once, here, when already cancelled). An HTTP
  // brain closes its socket in it, so a stop frees the connection at once. Must not block.
  void on_cancel(std::function<void()> callback) const {
    {
      std::lock_guard lock(state_->mutex);
      if (!state_->cancelled.load()) {
        state_->callbacks.push_back(std::move(callback));
        return;
      }
    }
    callback();
  }
  void cancel() const noexcept {
    std::vector<std::function<void()>> run;
    {
      std::lock_guard lock(state_->mutex);
      if (state_->cancelled.exchange(true)) return;
      run.swap(state_->callbacks);
    }
    for (auto& callback : run) try {
        callback();
      } catch (...) {  // a brain's cleanup never stops the others'
      }
  }

 private:
  struct State {
    std::atomic<bool> cancelled{false};
    std::mutex mutex;
    std::vector<std::function<void()>> callbacks;
  };
  std::shared_ptr<State> state_;
};

// A phrase the robot config maps to a command (custom capabilities declare what they understand this way).
struct BrainPhrase {
  std::string text;  // "close the gripper"
  Json action;       // the command it stands for, as in Proposal::action
};

// What a brain may know about the robot. Built by chat for each call.
struct BrainContext {
  std::vector<std::string> capabilities;  // declared: rcan_protocol.capabilities
  std::vector<BrainPhrase> phrases;       // configured phrases, in order
  // The bounds chat will enforce (a brain may use them to phrase its answer; chat checks them regardless):
  // {"max_linear_speed", "max_distance_m", "max_turn_deg", "max_duration_ms", "physics": {...}}.
  Json limits = Json::object();
  std::optional<Pose2d> pose;  // where the robot is, when something offers a PoseSource
};

struct BrainRequest {
  std::string instruction;                         // already checked by chat: non-empty, bounded, no controls
  std::string image_b64;                           // optional camera image (base64 JPEG or PNG); "" when none
  std::chrono::steady_clock::time_point deadline;  // answer by then; chat discards a later answer
};

// A brain's answer. `action` is exactly one HTTP request a client could have made:
//   {"method": "POST", "path": "/api/action", "body": {"type": "move", "linear": 0.5, "duration_ms": 2000}}
// (the same bodies as POST /api/action, POST /api/nav/waypoint and /api/cap/<name>/... calls; GETs have no body).
// Null: not understood; then `suggestions` lists the closest commands the brain knows.
struct Proposal {
  std::string raw_text;   // what the brain said (the grammar brain: its reading of the instruction)
  std::string reasoning;  // why, when the brain says (a model's chain of thought); shown only to scope `config`
  Json action;            // null when not understood
  std::vector<std::string> suggestions;
  std::optional<double> confidence;  // in [0, 1]; absent when the brain cannot say (a gate then counts a miss)
  std::string brain;                 // provider, e.g. "grammar"
  std::string model;                 // e.g. "grammar-en-1"
  std::string error;                 // non-empty: the brain failed (timeout, bad answer); a chain tries the next
};

class RCAND_INTERFACE Brain {
 public:
  virtual ~Brain() = default;
  virtual std::string_view provider() const noexcept = 0;
  // Blocks until the brain answers, `cancel` fires, or the deadline passes (then error is set). Thread-safe: chat
  // calls it from several workers at once. Never throws.
  virtual Proposal propose(const BrainRequest& request, const BrainContext& context, CancelToken cancel) const noexcept = 0;
};

// The service id a brain plugin offers its Brain under: "rcand.brain.<provider>/1".
inline std::string brain_service_id(std::string_view provider) { return "rcand.brain." + std::string(provider) + "/1"; }

}  // namespace rcand::sdk
