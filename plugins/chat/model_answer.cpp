#include "model_answer.hpp"

#include <rcand/sdk/request_body.hpp>

#include <cmath>

#include "proposal_guard.hpp"

namespace rcand::plugins::chat {
namespace {

using sdk::Json;

// Longer texts are cut (guard_proposal cuts them again, with the secrets redacted first): they are shown and logged,
// never acted on; copying no more than this keeps a megabyte answer from being copied around first.
std::string bounded(const std::string& text, std::size_t max_bytes = kMaxReplyBytes + 1024) {
  return sdk::bounded_utf8(text, max_bytes);
}

}  // namespace

const Json& answer_schema() {
  static const Json schema = Json::parse(R"({
    "type": "object",
    "additionalProperties": false,
    "required": ["reply", "action", "confidence"],
    "properties": {
      "reply": {"type": "string", "description": "one short sentence for the operator: what you understood"},
      "reasoning": {"type": "string", "description": "why this action, briefly"},
      "action": {"anyOf": [
        {"type": "null"},
        {"type": "object", "required": ["method", "path"], "properties": {
          "method": {"type": "string", "enum": ["GET", "POST"]},
          "path": {"type": "string"},
          "body": {"type": "object"}}}]},
      "confidence": {"type": "number", "minimum": 0, "maximum": 1},
      "suggestions": {"type": "array", "items": {"type": "string"}, "maxItems": 3}
    }
  })");
  return schema;
}

std::string system_prompt(const sdk::BrainContext& context) {
  std::string text =
      "You turn one operator instruction into at most one HTTP request to a robot's RCAN API. Answer only with the "
      "JSON object the schema describes. If the instruction is unclear, unsafe, or needs something this robot does "
      "not declare, answer action null, say why in reply, and suggest up to three commands it does understand. Never "
      "exceed the limits below; never guess a larger number. confidence is your probability (0 to 1) that the action "
      "is exactly what the operator meant.\n\nDeclared capabilities: ";
  for (std::size_t i = 0; i < context.capabilities.size(); ++i) text += (i ? ", " : "") + context.capabilities[i];
  text +=
      "\n\nRequests you may propose:\n"
      "- POST /api/stop {\"reason\": \"chat\"}: stop everything (the e-stop). Use it for stop, halt, freeze.\n"
      "- GET /api/status: the robot's status.\n"
      "- teleop: POST /api/action {\"type\": \"move\", \"linear\": -1..1, \"angular\": -1..1, \"duration_ms\": int} "
      "(positive angular turns left).\n"
      "- nav: POST /api/nav/waypoint {\"distance_m\": m, \"heading_deg\": deg (positive left, relative), \"speed\": 0..1}; "
      "POST /api/nav/cancel; GET /api/nav/status.\n"
      "- vision: GET /api/depth/obstacles (what is in front), GET /api/stream/snapshot (a picture).\n"
      "- arm: POST /api/action {\"type\": \"grip\", \"state\": \"open\"|\"close\"}.\n"
      "- custom capabilities: the configured phrases below.\n"
      "Only propose requests of declared capabilities.\n\nLimits: " +
      context.limits.dump();
  if (!context.phrases.empty()) {
    text += "\n\nConfigured phrases (instruction -> request):";
    for (const auto& phrase : context.phrases) text += "\n- \"" + phrase.text + "\" -> " + phrase.action.dump();
  }
  if (context.pose)
    text += "\n\nCurrent pose: x " + std::to_string(context.pose->x_m) + " m, y " + std::to_string(context.pose->y_m) +
            " m, heading " + std::to_string(context.pose->heading_deg) + " deg.";
  return text;
}

sdk::Proposal read_model_answer(std::string_view content) {
  sdk::Proposal p;
  const Json answer = Json::parse(content, nullptr, false);
  if (answer.is_discarded()) {
    p.error = "the model's answer is not JSON";
    return p;
  }
  if (!answer.is_object()) {
    p.error = "the model's answer is not a JSON object";
    return p;
  }
  if (const auto reply = answer.find("reply"); reply != answer.end()) {
    if (!reply->is_string()) {
      p.error = "the model's reply is not a string";
      return p;
    }
    p.raw_text = bounded(reply->get_ref<const std::string&>());
  }
  if (const auto reasoning = answer.find("reasoning"); reasoning != answer.end() && reasoning->is_string())
    p.reasoning = bounded(reasoning->get_ref<const std::string&>());
  if (const auto confidence = answer.find("confidence"); confidence != answer.end() && !confidence->is_null()) {
    const double value = confidence->is_number() ? confidence->get<double>() : NAN;
    if (!std::isfinite(value) || value < 0 || value > 1) {
      // Quoted bounded: a hostile model's confidence may be a 200 KB string (kept whole, it went into the answer,
      // the thought and the log line).
      p.error = "the model's confidence (" + sdk::describe_value(*confidence, 40) + ") is not a number in [0, 1]";
      return p;
    }
    p.confidence = value;  // absent stays absent: a gate counts it a miss
  }
  const auto action = answer.find("action");
  if (action == answer.end()) {
    p.error = "the model's answer has no action (null when it did not understand)";
    return p;
  }
  if (!action->is_null()) {
    if (!action->is_object() || !action->contains("method") || !(*action)["method"].is_string() || !action->contains("path") ||
        !(*action)["path"].is_string()) {
      p.error = "the model's action is not a request {method, path, body?}";
      return p;
    }
    p.action = *action;  // checked against the declared capabilities and bounds by chat
  }
  if (const auto suggestions = answer.find("suggestions"); suggestions != answer.end() && suggestions->is_array())
    for (const auto& s : *suggestions)
      if (s.is_string() && p.suggestions.size() < kMaxSuggestions)
        p.suggestions.push_back(bounded(s.get<std::string>(), kMaxSuggestionBytes + 1024));
  return p;
}

}  // namespace rcand::plugins::chat
