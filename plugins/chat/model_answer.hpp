// What chat asks a language model and what it accepts back, the same for every wire format (OpenAI-compatible chat
// completions, Ollama): a system prompt describing this robot's declared capabilities, their request bodies and
// bounds, and a JSON schema the server constrains the answer to (response_format json_schema / Ollama's format):
//   {"reply": "...", "reasoning": "...", "action": {"method","path","body"?} | null, "confidence": 0..1,
//    "suggestions": ["..."]}
// The schema is a request to the server, not a guarantee: read_model_answer() checks the answer again and treats
// anything off-schema (not JSON, a confidence outside [0, 1], an action that is not a request) as the brain failing,
// so the chain moves on. Whether the action is allowed is chat's action check, as for every brain.
#pragma once

#include <rcand/sdk/interfaces/brain.hpp>

#include <string>
#include <string_view>

namespace rcand::plugins::chat {

// The JSON schema of the answer.
const sdk::Json& answer_schema();

// The system prompt for this robot (capabilities, request formats, limits, configured phrases, pose).
std::string system_prompt(const sdk::BrainContext& context);

// The model's answer text parsed into a Proposal (brain and model left for the caller); on anything off-schema the
// Proposal's error says what, and its action is null.
sdk::Proposal read_model_answer(std::string_view content);

}  // namespace rcand::plugins::chat
