// A language model behind HTTP as a brain: an OpenAI-compatible chat completions server (llama.cpp server, vLLM,
// LM Studio, hosted APIs; the answer constrained by response_format json_schema) or Ollama's native /api/chat (the
// answer constrained by `format`). One propose() is one exchange (HttpExchange), retried with exponential backoff
// only when nothing reached the server or the server says it is overloaded (429, 502, 503, 504) and the next try
// still fits before the deadline; a 500, a bad answer, a timeout after the request was sent are the brain failing,
// and the chain moves on at once. The API key (from a file or an environment variable) goes into the Authorization
// header and nowhere else: every error text is scrubbed of it before it is logged or answered.
//
// Configured under runtime.capabilities.chat.brains.<provider> (ruling; README "HTTP brains"):
//   kind: openai | ollama (default: the provider's name when it is one of those), url, model (default agent.model
//   for agent.provider), api_key_file | api_key_env, timeout_ms (one call, retries included), connect_timeout_ms,
//   first_byte_timeout_ms (the wait for the answer, where a cold model load shows), retries, backoff_ms,
//   max_answer_bytes, ca_file (a private CA for https), health_interval_ms.
#pragma once

#include <rcand/sdk/config_view.hpp>
#include <rcand/sdk/interfaces/brain.hpp>

#include <boost/asio/ssl/context.hpp>

#include <chrono>
#include <memory>
#include <mutex>
#include <string>

#include "http_exchange.hpp"

namespace rcand::plugins::chat {

enum class WireFormat { OpenAI, Ollama };

struct ModelBrainSettings {
  std::string provider;  // the name agent.provider / agent.fallbacks use
  WireFormat format = WireFormat::OpenAI;
  std::string url;
  Endpoint endpoint;
  std::string model;
  std::string api_key;      // never logged or answered
  std::string key_source;   // "file <path>" / "env <NAME>" / "" - what status shows instead
  std::string setup_error;  // non-empty: the brain cannot work (an unreadable key file); every call fails with it
  std::chrono::milliseconds timeout{30000}, connect_timeout{2000}, first_byte_timeout{30000}, backoff{200};
  int retries = 2;
  std::size_t max_answer_bytes = 256 * 1024;
  std::string ca_file;
  std::chrono::milliseconds health_interval{30000};
};

// runtime.capabilities.chat.brains.<provider> (may be absent for "openai" and "ollama": their defaults), with `model`
// from agent.model / the fallback item when the block has none. Throws sdk::ConfigError naming the key at fault.
ModelBrainSettings read_model_brain(const std::string& provider, const sdk::Json& block, const std::string& model);

class ModelBrain final : public sdk::Brain {
 public:
  explicit ModelBrain(ModelBrainSettings settings);
  std::string_view provider() const noexcept override { return settings_.provider; }
  sdk::Proposal propose(const sdk::BrainRequest& request, const sdk::BrainContext& context,
                        sdk::CancelToken cancel) const noexcept override;

  // The health probe (GET <url>/models, or /api/tags for Ollama): blocks up to `timeout`; keeps and returns
  // {"ok", "status"?, "latency_ms", "model_listed"?, "error"?}. Cancelled by `cancel` (shutdown).
  sdk::Json probe(std::chrono::milliseconds timeout, const sdk::CancelToken& cancel) const noexcept;
  // The last probe's result (null before the first). Never blocks beyond a copy.
  sdk::Json health() const;
  // For status(): kind, url, model, key source - never the key.
  sdk::Json describe() const;
  const ModelBrainSettings& settings() const noexcept { return settings_; }
  // `text` with the API key replaced by "[api key]".
  std::string redact(std::string text) const;

 private:
  std::string request_body(const sdk::BrainRequest& request, const sdk::BrainContext& context) const;
  sdk::Proposal read_reply(const std::string& body) const;
  std::map<std::string, std::string> headers() const;

  const ModelBrainSettings settings_;
  std::unique_ptr<boost::asio::ssl::context> tls_;  // https endpoints only
  mutable std::mutex health_mutex_;
  mutable sdk::Json health_;
};

}  // namespace rcand::plugins::chat
