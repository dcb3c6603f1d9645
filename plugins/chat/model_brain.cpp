#include "model_brain.hpp"
#include "trimmed.hpp"

#include <rcand/sdk/request_body.hpp>

#include <boost/beast/http/verb.hpp>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "model_answer.hpp"
#include "proposal_guard.hpp"

namespace rcand::plugins::chat {
namespace {

using sdk::ConfigError;
using sdk::Json;
using std::chrono::milliseconds;
namespace http = boost::beast::http;

constexpr milliseconds kShortestTry{50};  // a retry that could not even connect in this time is not worth starting

std::chrono::milliseconds read_ms(const Json& block, const std::string& where, const char* key, milliseconds fallback,
                                  long long max = 600000) {
  const auto it = block.find(key);
  if (it == block.end()) return fallback;
  if (!it->is_number_integer() || it->get<long long>() < 1 || it->get<long long>() > max)
    throw ConfigError(where + "." + key + ": expected an integer in [1, " + std::to_string(max) + "] (milliseconds)");
  return milliseconds(it->get<long long>());
}

std::string read_string(const Json& block, const std::string& where, const char* key) {
  const auto it = block.find(key);
  if (it == block.end()) return {};
  if (!it->is_string() || it->get<std::string>().empty()) throw ConfigError(where + "." + key + ": expected a non-empty string");
  return it->get<std::string>();
}

// The server's own error message, short and printable (OpenAI {"error": {"message"}}, Ollama {"error": "..."}).
std::string excerpt(const std::string& body) {
  const Json parsed = Json::parse(body, nullptr, false);
  std::string text = body;
  if (parsed.is_object() && parsed.contains("error")) {
    const Json& error = parsed["error"];
    if (error.is_string()) text = error.get<std::string>();
    else if (error.is_object() && error.contains("message") && error["message"].is_string())
      text = error["message"].get<std::string>();
  }
  text = sdk::bounded_utf8(text, 200);
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20) c = ' ';
  return text.empty() ? "" : ": " + text;
}

}  // namespace

ModelBrainSettings read_model_brain(const std::string& provider, const Json& block_in, const std::string& model) {
  const std::string where = "runtime.capabilities.chat.brains." + provider;
  if (!block_in.is_null() && !block_in.is_object()) throw ConfigError(where + ": expected a mapping (kind, url, model, ...)");
  const Json block = block_in.is_null() ? Json::object() : block_in;
  static const std::vector<std::string> kKeys{"kind",
                                              "url",
                                              "model",
                                              "api_key_file",
                                              "api_key_env",
                                              "timeout_ms",
                                              "connect_timeout_ms",
                                              "first_byte_timeout_ms",
                                              "retries",
                                              "backoff_ms",
                                              "max_answer_bytes",
                                              "ca_file",
                                              "health_interval_ms"};
  for (const auto& [key, value] : block.items())
    if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end())
      throw ConfigError(where + "." + key +
                        ": unknown key (kind, url, model, api_key_file, api_key_env, timeout_ms, "
                        "connect_timeout_ms, first_byte_timeout_ms, retries, backoff_ms, max_answer_bytes, "
                        "ca_file, health_interval_ms)");
  ModelBrainSettings s;
  s.provider = provider;
  std::string kind = read_string(block, where, "kind");
  if (kind.empty()) kind = provider;
  if (kind == "openai") s.format = WireFormat::OpenAI;
  else if (kind == "ollama") s.format = WireFormat::Ollama;
  else throw ConfigError(where + ".kind: openai or ollama (the wire format of the model server)");
  s.url = read_string(block, where, "url");
  if (s.url.empty()) s.url = s.format == WireFormat::Ollama ? "http://127.0.0.1:11434" : "https://api.openai.com/v1";
  std::string why;
  const auto endpoint = parse_endpoint(s.url, why);
  if (!endpoint) throw ConfigError(where + ".url: " + why);
  s.endpoint = *endpoint;
  s.model = read_string(block, where, "model");
  if (s.model.empty()) s.model = model;
  if (s.model.empty()) throw ConfigError(where + ".model: required (or agent.model, or the fallback's model)");

  const std::string key_file = read_string(block, where, "api_key_file");
  const std::string key_env = read_string(block, where, "api_key_env");
  if (!key_file.empty() && !key_env.empty()) throw ConfigError(where + ": api_key_file or api_key_env, not both");
  // An unreadable key makes this brain fail (the chain moves on, status says why) rather than the whole of chat.
  if (!key_file.empty()) {
    s.key_source = "file " + key_file;
    std::ifstream in(key_file);
    std::stringstream text;
    if (in) text << in.rdbuf();
    if (!in) s.setup_error = "cannot read api_key_file " + key_file + ": " + std::strerror(errno);
    else s.api_key = trimmed(text.str());
  } else if (!key_env.empty()) {
    s.key_source = "env " + key_env;
    const char* value = std::getenv(key_env.c_str());
    if (value == nullptr || *value == '\0') s.setup_error = "the environment variable " + key_env + " (api_key_env) is not set";
    else s.api_key = trimmed(value);
  }
  if (s.setup_error.empty() && !s.key_source.empty()) {
    if (s.api_key.empty()) s.setup_error = "the API key (" + s.key_source + ") is empty";
    for (const char c : s.api_key)
      if (static_cast<unsigned char>(c) < 0x21 || c == 0x7f)
        s.setup_error = "the API key (" + s.key_source + ") has spaces or control characters";
    if (!s.setup_error.empty()) s.api_key.clear();
  }

  s.timeout = read_ms(block, where, "timeout_ms", s.timeout);
  s.connect_timeout = read_ms(block, where, "connect_timeout_ms", s.connect_timeout);
  s.first_byte_timeout = read_ms(block, where, "first_byte_timeout_ms", s.first_byte_timeout);
  s.backoff = read_ms(block, where, "backoff_ms", s.backoff, 60000);
  s.health_interval = read_ms(block, where, "health_interval_ms", s.health_interval, 3600000);
  if (const auto it = block.find("retries"); it != block.end()) {
    if (!it->is_number_integer() || it->get<int>() < 0 || it->get<int>() > 10)
      throw ConfigError(where + ".retries: expected an integer in [0, 10]");
    s.retries = it->get<int>();
  }
  if (const auto it = block.find("max_answer_bytes"); it != block.end()) {
    if (!it->is_number_integer() || it->get<long long>() < 1024 || it->get<long long>() > (64 << 20))
      throw ConfigError(where + ".max_answer_bytes: expected an integer in [1024, 67108864]");
    s.max_answer_bytes = it->get<std::size_t>();
  }
  s.ca_file = read_string(block, where, "ca_file");
  return s;
}

ModelBrain::ModelBrain(ModelBrainSettings settings) : settings_(std::move(settings)) {
  if (settings_.endpoint.tls) {
    try {
      tls_ = make_tls_context(settings_.ca_file);
    } catch (const std::exception& e) {
      throw ConfigError("runtime.capabilities.chat.brains." + settings_.provider + ".ca_file: " + e.what());
    }
  }
}

std::string ModelBrain::redact(std::string text) const { return redact_secrets(std::move(text), {settings_.api_key}); }

std::map<std::string, std::string> ModelBrain::headers() const {
  if (settings_.api_key.empty()) return {};
  return {{"Authorization", "Bearer " + settings_.api_key}};
}

std::string ModelBrain::request_body(const sdk::BrainRequest& request, const sdk::BrainContext& context) const {
  Json system{{"role", "system"}, {"content", system_prompt(context)}};
  Json user{{"role", "user"}, {"content", request.instruction}};
  if (settings_.format == WireFormat::Ollama) {
    if (!request.image_b64.empty()) user["images"] = Json::array({request.image_b64});
    return Json{{"model", settings_.model},
                {"messages", {system, user}},
                {"format", answer_schema()},
                {"stream", false},
                {"options", {{"temperature", 0}}}}
        .dump();
  }
  if (!request.image_b64.empty()) {
    const char* type = request.image_b64.starts_with("iVBOR") ? "image/png" : "image/jpeg";  // PNG's magic, in base64
    user["content"] = Json::array(
        {{{"type", "text"}, {"text", request.instruction}},
         {{"type", "image_url"}, {"image_url", {{"url", std::string("data:") + type + ";base64," + request.image_b64}}}}});
  }
  return Json{
      {"model", settings_.model},
      {"messages", {system, user}},
      {"response_format",
       {{"type", "json_schema"}, {"json_schema", {{"name", "rcan_command"}, {"strict", false}, {"schema", answer_schema()}}}}},
      {"temperature", 0},
      {"max_tokens", 512},
      {"stream", false}}
      .dump();
}

// The server's envelope around the model's text: OpenAI choices[0].message.content, Ollama message.content.
sdk::Proposal ModelBrain::read_reply(const std::string& body) const {
  sdk::Proposal p;
  const Json reply = Json::parse(body, nullptr, false);
  static const Json kNone;
  const Json* message = &kNone;
  if (reply.is_object()) {
    if (settings_.format == WireFormat::OpenAI) {
      const auto choices = reply.find("choices");
      if (choices != reply.end() && choices->is_array() && !choices->empty() && (*choices)[0].is_object() &&
          (*choices)[0].contains("message"))
        message = &(*choices)[0]["message"];
    } else if (const auto m = reply.find("message"); m != reply.end()) {
      message = &*m;
    }
  }
  if (message->is_object() && message->contains("refusal") && (*message)["refusal"].is_string()) {
    p.error = "the model refused" + excerpt(Json{{"error", (*message)["refusal"]}}.dump());
    return p;
  }
  const Json* content = message->is_object() && message->contains("content") ? &(*message)["content"] : nullptr;
  if (content == nullptr || !content->is_string()) {
    p.error =
        reply.is_discarded() ? "the server's answer is not JSON" : "the server's answer has no message content" + excerpt(body);
    return p;
  }
  return read_model_answer(content->get<std::string>());
}

sdk::Proposal ModelBrain::propose(const sdk::BrainRequest& request, const sdk::BrainContext& context,
                                  sdk::CancelToken cancel) const noexcept {
  sdk::Proposal p;
  try {
    if (!settings_.setup_error.empty()) {
      p.error = settings_.setup_error;
    } else {
      const auto deadline = std::min(request.deadline, Clock::now() + settings_.timeout);
      const std::string body = request_body(request, context);
      const char* target = settings_.format == WireFormat::OpenAI ? "/chat/completions" : "/api/chat";
      const ExchangeLimits limits{settings_.connect_timeout, settings_.first_byte_timeout, deadline, settings_.max_answer_bytes};
      HttpExchange exchange(cancel, tls_.get());
      for (int attempt = 0;; ++attempt) {
        const ExchangeResult r = exchange.run(settings_.endpoint, http::verb::post, target, body, headers(), limits);
        if (r.cancelled) {
          p.error = "cancelled";
          break;
        }
        if (r.status == 200) {
          p = read_reply(r.body);
          break;
        }
        const bool overloaded = r.status == 429 || r.status == 502 || r.status == 503 || r.status == 504;
        const milliseconds wait = settings_.backoff * (1 << attempt);
        if ((r.retryable || overloaded) && attempt < settings_.retries && Clock::now() + wait + kShortestTry < deadline) {
          if (exchange.pause(wait)) continue;
          p.error = "cancelled";
          break;
        }
        p.error = (r.status == 0 ? r.error : "HTTP " + std::to_string(r.status) + " from the model server" + excerpt(r.body)) +
                  (attempt > 0 ? " (after " + std::to_string(attempt + 1) + " tries)" : "");
        break;
      }
    }
  } catch (const std::exception& e) {
    p = {};
    p.error = e.what();
  }
  p.brain = settings_.provider;
  p.model = settings_.model;
  // Everything the model returned, its key redacted (a server may echo it into any field) and bounded; chat guards
  // every brain's proposal again with all the keys it knows.
  return guard_proposal(std::move(p), {settings_.api_key});
}

Json ModelBrain::probe(milliseconds timeout, const sdk::CancelToken& cancel) const noexcept {
  Json result;
  try {
    const auto started = Clock::now();
    if (!settings_.setup_error.empty()) {
      result = {{"ok", false}, {"error", settings_.setup_error}};
    } else {
      HttpExchange exchange(cancel, tls_.get());
      const ExchangeLimits limits{std::min(settings_.connect_timeout, timeout), timeout, started + timeout, 4 << 20};
      const char* target = settings_.format == WireFormat::OpenAI ? "/models" : "/api/tags";
      const ExchangeResult r = exchange.run(settings_.endpoint, http::verb::get, target, "", headers(), limits);
      result = {{"ok", r.status == 200}};
      if (r.status != 0) result["status"] = r.status;
      if (r.status != 200)
        result["error"] = redact(r.status == 0 ? r.error : "HTTP " + std::to_string(r.status) + excerpt(r.body));
      const Json list = r.status == 200 ? Json::parse(r.body, nullptr, false) : Json();
      if (list.is_object()) {  // is the configured model among those the server lists?
        bool listed = false;
        const Json& items = list.value(settings_.format == WireFormat::OpenAI ? "data" : "models", Json::array());
        for (const auto& item : items.is_array() ? items : Json::array()) {
          const std::string name = item.is_object() ? item.value(settings_.format == WireFormat::OpenAI ? "id" : "name", "") : "";
          listed |= name == settings_.model || name == settings_.model + ":latest";
        }
        result["model_listed"] = listed;
      }
    }
    result["latency_ms"] = std::chrono::duration<double, std::milli>(Clock::now() - started).count();
  } catch (const std::exception& e) {
    result = {{"ok", false}, {"error", redact(e.what())}};
  }
  std::lock_guard lock(health_mutex_);
  health_ = result;
  return result;
}

Json ModelBrain::health() const {
  std::lock_guard lock(health_mutex_);
  return health_;
}

Json ModelBrain::describe() const {
  Json d{{"kind", settings_.format == WireFormat::OpenAI ? "openai" : "ollama"},
         {"url", settings_.url},
         {"model", settings_.model},
         {"timeout_ms", settings_.timeout.count()},
         {"api_key", settings_.key_source.empty() ? Json(nullptr) : Json(settings_.key_source)},
         {"health", health()}};
  if (!settings_.setup_error.empty()) d["error"] = settings_.setup_error;
  return d;
}

}  // namespace rcand::plugins::chat
