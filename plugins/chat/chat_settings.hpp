// chat's settings: its own (runtime.capabilities.chat, schema and defaults in manifests/chat.json) and what it reads
// from the robot config - the RCAN agent block (provider, model, fallbacks, confidence_gates), the declared
// capabilities, safety.max_linear_speed, the physics block and nav's max_job_ms - all read once at startup.
//
// Phrases (ruling: how a custom capability says what it understands). The robot config maps phrases to requests:
//   runtime.capabilities.chat.phrases:
//     - say: ["close the gripper", "grab it"]       # one phrase or a list; filler words ("the", "please") are ignored
//       action: {method: POST, path: /api/cap/com.acme.gripper/grip, body: {state: close}}
// The robot's integrator writes them, next to the capability they drive; chat checks each action like any brain's.
#pragma once

#include <rcand/sdk/config_view.hpp>
#include <rcand/sdk/interfaces/brain.hpp>

#include <chrono>
#include <string>
#include <vector>

#include "action_check.hpp"
#include "confidence_gate.hpp"
#include "hitl.hpp"
#include "model_brain.hpp"

namespace rcand::plugins::chat {

// What chat keeps of runtime.handler_timeout_ms for itself: the grammar brain, the dispatch and the answer.
inline constexpr std::chrono::milliseconds kHandlerMargin{500};
// What a failing brain chain keeps for the grammar brain (microseconds of work) at the end of the deadline.
inline constexpr std::chrono::milliseconds kGrammarReserve{50};

struct ChatSettings {
  std::size_t workers = 2;       // brain calls at once
  std::size_t queue_limit = 16;  // instructions waiting beyond those; more answer 429
  std::size_t max_instruction_chars = 2000;
  std::size_t max_image_bytes = 1 << 20;  // of image_b64, as sent
  // The brains' deadline, from when the instruction came in: timeout_ms, capped below runtime.handler_timeout_ms
  // (after which the kernel answers 503 itself) by kHandlerMargin, so chat always gives its own answer.
  std::chrono::milliseconds timeout{5000};
  bool timeout_capped = false;                   // timeout_ms was cut to fit runtime.handler_timeout_ms
  std::vector<std::string> ignored;              // settings read and left out, each logged once at start
  std::vector<std::string> providers;            // agent.provider, then agent.fallbacks, then "grammar" (always last)
  std::string model;                             // agent.model ("" when not given)
  std::vector<ModelBrainSettings> model_brains;  // the HTTP brains among the providers (runtime.capabilities.chat.brains)
  std::vector<sdk::BrainPhrase> phrases;
  std::vector<ConfidenceGate> gates;
  std::vector<HitlGate> hitl_gates;
  std::size_t thought_log_size = 256;                   // thoughts GET /api/thoughts/<id> still knows
  std::size_t hitl_limit = 32;                          // actions waiting for approval at once
  std::size_t hitl_per_principal = 8;                   // of one principal below OWNER
  std::size_t hitl_reserved = 8;                        // the last slots, for OWNER and CREATOR only (default: a quarter)
  std::chrono::milliseconds escalation_timeout{30000};  // an escalated action's wait when no HiTL gate names it
  ActionLimits limits;
};

// Throws sdk::ConfigError naming the key at fault.
ChatSettings read_chat_settings(const sdk::ConfigView& own, const sdk::ConfigView& robot);

// What a brain may know about the limits (sdk::BrainContext::limits).
sdk::Json limits_json(const ActionLimits& limits);

}  // namespace rcand::plugins::chat
