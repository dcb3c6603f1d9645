#include "chat_settings.hpp"

#include <algorithm>
#include <cmath>

namespace rcand::plugins::chat {
namespace {

using sdk::ConfigError;
using sdk::Json;

std::vector<sdk::BrainPhrase> read_phrases(const Json& list) {
  std::vector<sdk::BrainPhrase> phrases;
  if (list.is_null()) return phrases;
  if (!list.is_array()) throw ConfigError("runtime.capabilities.chat.phrases: expected a list of {say, action}");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = "runtime.capabilities.chat.phrases[" + std::to_string(i) + "]";
    const Json& item = list[i];
    if (!item.is_object() || !item.contains("say") || !item.contains("action"))
      throw ConfigError(where + ": expected {say: \"...\" or [...], action: {method, path, body}}");
    const Json& action = item["action"];
    if (!action.is_object() || !action.contains("method") || !action["method"].is_string() || !action.contains("path") ||
        !action["path"].is_string())
      throw ConfigError(where + ".action: expected {method, path, body}");
    Json says = item["say"].is_string() ? Json::array({item["say"]}) : item["say"];
    if (!says.is_array() || says.empty()) throw ConfigError(where + ".say: a phrase, or a non-empty list of phrases");
    for (const auto& say : says) {
      if (!say.is_string() || say.get<std::string>().empty() || say.get<std::string>().size() > 200)
        throw ConfigError(where + ".say: phrases are non-empty strings of at most 200 characters");
      phrases.push_back({say.get<std::string>(), action});
    }
  }
  return phrases;
}

// The chain's providers, each with the model it names ("" when none: the brain's own setting decides).
std::vector<std::pair<std::string, std::string>> read_providers(const sdk::ConfigView& robot) {
  std::vector<std::pair<std::string, std::string>> providers;
  auto add = [&](const std::string& name, const std::string& model) {
    if (name.empty()) return;
    for (const auto& p : providers)
      if (p.first == name) return;
    providers.emplace_back(name, model);
  };
  add(robot.get<std::string>("agent.provider").value_or("grammar"), robot.get<std::string>("agent.model").value_or(""));
  const Json& fallbacks = robot.sub("agent").raw().value("fallbacks", Json::array());
  if (!fallbacks.is_array()) throw ConfigError("agent.fallbacks: expected a list of providers");
  for (const auto& f : fallbacks) {
    // A fallback is a provider name, or a mapping naming one ({provider: ollama, model: ...}).
    if (f.is_string()) add(f.get<std::string>(), "");
    else if (f.is_object() && f.contains("provider") && f["provider"].is_string())
      add(f["provider"].get<std::string>(), f.contains("model") && f["model"].is_string() ? f["model"].get<std::string>() : "");
    else throw ConfigError("agent.fallbacks: each item is a provider name or {provider: ..., model: ...}");
  }
  add("grammar", "");  // the embedded brain always answers last: no network, no model
  return providers;
}

// The HTTP brains: every provider of the chain with a runtime.capabilities.chat.brains entry, and "openai" /
// "ollama" with their defaults. Others are brain plugins (or none: that provider fails and the chain moves on).
std::vector<ModelBrainSettings> read_model_brains(const Json& brains,
                                                  const std::vector<std::pair<std::string, std::string>>& providers) {
  if (!brains.is_null() && !brains.is_object())
    throw ConfigError("runtime.capabilities.chat.brains: expected a mapping of provider names to {kind, url, model, ...}");
  std::vector<ModelBrainSettings> out;
  for (const auto& [provider, model] : providers) {
    const bool configured = brains.is_object() && brains.contains(provider);
    if (provider == "grammar") {
      if (configured) throw ConfigError("runtime.capabilities.chat.brains.grammar: the embedded brain takes no settings");
      continue;
    }
    if (configured || provider == "openai" || provider == "ollama")
      out.push_back(read_model_brain(provider, configured ? brains[provider] : Json(), model));
  }
  return out;
}

}  // namespace

ChatSettings read_chat_settings(const sdk::ConfigView& own, const sdk::ConfigView& robot) {
  ChatSettings s;
  s.workers = static_cast<std::size_t>(own.get_or<long long>("workers", 2));
  s.queue_limit = static_cast<std::size_t>(own.get_or<long long>("queue_limit", 16));
  s.max_instruction_chars = static_cast<std::size_t>(own.get_or<long long>("max_instruction_chars", 2000));
  s.max_image_bytes = static_cast<std::size_t>(own.get_or<long long>("max_image_bytes", 1 << 20));
  // The kernel answers 503 for a stream route that has not answered within runtime.handler_timeout_ms: the brain's
  // deadline ends before it, so the caller gets chat's own answer.
  const long long handler_ms = robot.get_or<long long>("runtime.handler_timeout_ms", 10000);
  const long long timeout_ms = own.get_or<long long>("timeout_ms", 5000);
  const long long cap = handler_ms - kHandlerMargin.count();
  s.timeout = std::chrono::milliseconds(std::max<long long>(10, std::min(timeout_ms, cap)));
  s.timeout_capped = timeout_ms > cap;
  const auto providers = read_providers(robot);
  for (const auto& p : providers) s.providers.push_back(p.first);
  s.model = robot.get<std::string>("agent.model").value_or("");
  s.model_brains = read_model_brains(own.raw().value("brains", Json()), providers);
  s.phrases = read_phrases(own.raw().value("phrases", Json::array()));
  s.gates = read_confidence_gates(robot, &s.ignored);
  s.hitl_gates = read_hitl_gates(robot);
  s.thought_log_size = static_cast<std::size_t>(own.get_or<long long>("thought_log_size", 256));
  s.hitl_limit = static_cast<std::size_t>(own.get_or<long long>("hitl_limit", 32));
  s.hitl_per_principal = static_cast<std::size_t>(own.get_or<long long>("hitl_per_principal", 8));
  s.hitl_reserved = static_cast<std::size_t>(own.get_or<long long>("hitl_reserved", static_cast<long long>(s.hitl_limit / 4)));
  if (s.hitl_reserved > 0 && s.hitl_reserved >= s.hitl_limit)
    throw ConfigError("runtime.capabilities.chat.hitl_reserved: must be below hitl_limit (" + std::to_string(s.hitl_limit) +
                      "): principals below OWNER need at least one slot");
  s.escalation_timeout = std::chrono::milliseconds(own.get_or<long long>("escalation_timeout_ms", 30000));

  ActionLimits& l = s.limits;
  const Json& caps = robot.sub("rcan_protocol").raw().value("capabilities", Json::array());
  if (caps.is_array())
    for (const auto& c : caps)
      if (c.is_string()) l.declared.push_back(c.get<std::string>());
  l.max_linear_speed = std::min(1.0, robot.get<double>("safety.max_linear_speed").value_or(1.0));
  if (!(l.max_linear_speed >= 0)) throw ConfigError("safety.max_linear_speed: expected a number >= 0");
  l.max_distance_m = own.get_or<double>("max_distance_m", 5.0);
  l.max_turn_deg = own.get_or<double>("max_turn_deg", 360.0);
  l.max_duration_ms = static_cast<int>(own.get_or<long long>("max_duration_ms", 10000));
  l.nav_max_job_ms = robot.get_or<long long>("runtime.capabilities.nav.max_job_ms", 600000);
  l.wheel_circumference_m = robot.get<double>("physics.wheel_circumference_m").value_or(0.0);
  l.turn_time_per_deg_s = robot.get<double>("physics.turn_time_per_deg_s").value_or(0.0);
  l.max_wheel_rps = robot.get<double>("physics.max_wheel_rps").value_or(1.0);
  return s;
}

Json limits_json(const ActionLimits& l) {
  return {{"max_linear_speed", l.max_linear_speed},
          {"max_distance_m", l.max_distance_m},
          {"max_turn_deg", l.max_turn_deg},
          {"max_duration_ms", l.max_duration_ms},
          {"physics",
           {{"wheel_circumference_m", l.wheel_circumference_m},
            {"turn_time_per_deg_s", l.turn_time_per_deg_s},
            {"max_wheel_rps", l.max_wheel_rps}}}};
}

}  // namespace rcand::plugins::chat
