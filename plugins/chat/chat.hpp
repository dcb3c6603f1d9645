// The chat capability (RCAN §9 chat, docs/protocol.md §7): POST /api/command {"instruction", "image_b64"?} ->
// {"raw_text", "action", "brain", "model", "thought_id", "confidence"?, "result"}. Never on the control path:
//   - the route is a stream route, so its handler (on the capability's worker) only checks the body and submits
//     the instruction to chat's own bounded BrainPool (429 with Retry-After when full); a pool worker answers later
//     through the StreamWriter;
//   - on the pool worker, in the RCAN gate order: injection scan (a block never reaches a brain), the brain chain
//     (agent.provider, agent.fallbacks, then the embedded grammar brain), the action check against the declared
//     capabilities and bounds, the confidence gate, the e-stop epoch, and the dispatch through rcand's
//     RequestDispatcher as the caller (principal and role), with the thought id as the dispatched message id - so
//     the kernel's scope check, 423 e-stop pre-check, audit entry and the capability's own handler all apply;
//   - agent.hitl_gates (and the confidence gate's `escalate`) hold an action for an OWNER's POST /api/hitl/authorize;
//     GET /api/hitl/pending lists the waits, GET /api/thoughts/<id> what each instruction became (ThoughtLog);
//   - on_estop() drops waiting instructions and waiting approvals, cancels the brains thinking (an HTTP brain's
//     socket closes at once), and bumps an epoch: an action decided before a stop is never dispatched after the
//     clear, approved or not.
#pragma once

#include <rcand/sdk/interfaces/brain.hpp>
#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/stream.hpp>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>

#include "brain_pool.hpp"
#include "chat_settings.hpp"
#include "command_input.hpp"
#include "grammar_brain.hpp"
#include "hitl.hpp"
#include "model_brain.hpp"
#include "thought_log.hpp"

namespace rcand::plugins::chat {

class Chat final : public sdk::Capability {
 public:
  explicit Chat(sdk::PluginContext& ctx);
  ~Chat() override;

  void start() override;  // the HTTP brains' first health probes
  std::vector<sdk::Route> routes() override;
  std::vector<sdk::StreamRoute> stream_routes() override;
  sdk::Json status() const override;
  void on_estop() noexcept override;
  void shutdown() noexcept override;

  // POST /api/command and POST /api/hitl/authorize (stream routes: they answer later, from chat's own threads).
  void command(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer);
  void authorize(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer);
  // GET /api/thoughts/<id> and GET /api/hitl/pending.
  sdk::Response thought(const sdk::Request& request) const;
  sdk::Response pending(const sdk::Request& request) const;
  const ChatSettings& settings() const noexcept { return settings_; }

 private:
  struct Thought;
  using Reply = HitlQueue::Reply;
  void think(const std::shared_ptr<Thought>& thought, const sdk::CancelToken& cancel) noexcept;
  sdk::Proposal ask_brains(const Thought& thought, const sdk::BrainContext& context, const sdk::CancelToken& cancel,
                           sdk::Json& attempts);
  sdk::BrainContext context() const;
  // Answers the instruction's caller and records the outcome in the thought log.
  void answer(const Thought& thought, const std::string& state, sdk::Response response,
              std::vector<std::pair<std::string, std::string>> headers = {});
  void hold(const std::shared_ptr<Thought>& thought, const sdk::Json& answer, const CheckedAction& action,
            const std::string& reason, std::chrono::milliseconds timeout, bool approve_on_timeout);
  void dispatch(const std::shared_ptr<Thought>& thought, const sdk::Json& answer, const CheckedAction& action, Reply reply);
  void probe(std::size_t brain) noexcept;
  void cancel_everything(std::uint64_t epoch) noexcept;  // on_estop()'s cleanup (of what came before `epoch`)

  sdk::PluginContext& ctx_;
  const ChatSettings settings_;
  const GrammarBrain grammar_;
  std::vector<std::unique_ptr<ModelBrain>> model_brains_;
  std::vector<std::string> secrets_;  // every HTTP brain's API key: redacted from whatever any brain returns
  BrainPool pool_;
  ThoughtLog thoughts_;
  HitlQueue hitl_;
  sdk::Worker& timer_;             // brain deadlines, approval timeouts
  sdk::Worker& canceller_;         // on_estop()'s cleanup, off the stop path
  sdk::Worker* health_ = nullptr;  // the HTTP brains' health probes (only when there are HTTP brains)
  struct Probes {
    std::mutex mutex;
    bool stopped = false;
    sdk::CancelToken running;          // the probe in progress (shutdown cancels it)
    std::vector<sdk::TimerId> timers;  // the next probe of each brain
  };
  Probes probes_;
  std::atomic<std::uint64_t> epoch_{0};  // bumped by every e-stop
  std::mutex dispatch_mutex_;            // an epoch check and its dispatch, against on_estop()
  struct Counters {
    std::atomic<std::uint64_t> received{0}, dispatched{0}, not_understood{0}, refused{0}, injection_blocked{0}, gate_blocked{0},
        busy{0}, cancelled{0}, held{0}, approved{0}, denied{0}, brain_failures{0};
  };
  mutable Counters counters_;
};

}  // namespace rcand::plugins::chat
