#include "libs/r2r_wire/envelope.hpp"

#include <array>
#include <cmath>
#include <utility>

#include "libs/base/bounded_text.hpp"
#include "libs/r2r_wire/payload_schema.hpp"

namespace rcand::r2r_wire {
namespace {

using nlohmann::json;

constexpr std::array<std::pair<MessageType, std::string_view>, 6> kTypes{{
    {MessageType::Status, "status"},
    {MessageType::TaskRequest, "task_request"},
    {MessageType::TaskResponse, "task_response"},
    {MessageType::Command, "command"},
    {MessageType::Negotiation, "negotiation"},
    {MessageType::Error, "error"},
}};

struct TooDeep {};

R2rError invalid(std::string field, std::string message) {
  R2rError error;
  error.code = ErrorCode::InvalidFormat;
  error.field = std::move(field);
  error.message = std::move(message);
  return error;
}

std::string found(const json& value) { return std::string(value.type_name()); }

// A non-empty string at header[key]; `required` says whether absence is a fault.
std::optional<R2rError> read_id(const json& header, const char* key, bool required, std::optional<std::string>& out) {
  const std::string field = std::string("/header/") + key;
  const auto it = header.find(key);
  if (it == header.end()) {
    if (required) return invalid(field, std::string("header.") + key + " is required: a non-empty string");
    return std::nullopt;
  }
  if (!it->is_string()) return invalid(field, std::string("header.") + key + " must be a string, found " + found(*it));
  if (it->get_ref<const std::string&>().empty()) return invalid(field, std::string("header.") + key + " must not be empty");
  if (it->get_ref<const std::string&>().size() > kMaxIdBytes)
    return invalid(
        field, std::string("header.") + key + " is longer than " + std::to_string(kMaxIdBytes) + " bytes (a robot name or RURI)");
  out = it->get<std::string>();
  return std::nullopt;
}

}  // namespace

std::string_view type_name(MessageType type) noexcept {
  for (const auto& [t, name] : kTypes)
    if (t == type) return name;
  return "status";
}

std::optional<MessageType> parse_message_type(std::string_view name) noexcept {
  for (const auto& [t, text] : kTypes)
    if (text == name) return t;
  return std::nullopt;
}

std::variant<Envelope, R2rError> parse_envelope(std::string_view bytes) {
  if (bytes.size() > kMaxMessageBytes)
    return invalid("", "message is " + std::to_string(bytes.size()) + " bytes, more than the " +
                           std::to_string(kMaxMessageBytes) + " allowed");
  json doc;
  try {
    // The depth limit runs inside the parser, so hostile nesting never builds a deep tree.
    doc = json::parse(bytes, [](int depth, json::parse_event_t, json&) {
      if (depth > kMaxMessageDepth) throw TooDeep{};
      return true;
    });
  } catch (const TooDeep&) {
    return invalid("", "message nests deeper than " + std::to_string(kMaxMessageDepth) + " levels");
  } catch (const json::exception& e) {
    return invalid("", std::string("message is not valid JSON: ") + e.what());
  }
  if (!doc.is_object()) return invalid("", "message must be a JSON object, found " + found(doc));

  // What an error reply needs, gathered before any fault is reported.
  std::optional<json> ref;
  std::optional<std::string> received_type, received_source;
  const auto header_it = doc.find("header");
  if (header_it != doc.end() && header_it->is_object()) {
    ref = error_ref(*header_it);
    if (const auto s = header_it->find("source_id"); s != header_it->end() && s->is_string() &&
                                                     !s->get_ref<const std::string&>().empty() &&
                                                     s->get_ref<const std::string&>().size() <= kMaxIdBytes)
      received_source = s->get<std::string>();
  }
  if (const auto t = doc.find("type"); t != doc.end() && t->is_string())
    received_type = bounded_text(t->get_ref<const std::string&>(), 64);  // only compared with "error"
  auto fail = [&](R2rError error) {
    error.ref = ref;
    error.type = received_type;
    error.source_id = received_source;
    return error;
  };

  if (header_it == doc.end()) return fail(invalid("/header", "header is required: an object"));
  if (!header_it->is_object()) return fail(invalid("/header", "header must be an object, found " + found(*header_it)));
  const json& header = *header_it;

  Envelope envelope;
  const auto version = header.find("version");
  if (version == header.end()) return fail(invalid("/header/version", "header.version is required: a string such as \"1.0\""));
  if (!version->is_string())
    return fail(invalid("/header/version", "header.version must be a string such as \"1.0\", found " + found(*version)));
  envelope.version = version->get<std::string>();
  if (envelope.version.empty()) return fail(invalid("/header/version", "header.version must not be empty"));

  const auto timestamp = header.find("timestamp");
  if (timestamp == header.end())
    return fail(invalid("/header/timestamp", "header.timestamp is required: Unix seconds (a number)"));
  if (!timestamp->is_number())
    return fail(invalid("/header/timestamp", "header.timestamp must be a number (Unix seconds), found " + found(*timestamp)));
  envelope.timestamp = timestamp->get<double>();
  if (!std::isfinite(envelope.timestamp) || envelope.timestamp < 0)
    return fail(invalid("/header/timestamp", "header.timestamp must be a finite number >= 0"));

  std::optional<std::string> source;
  if (auto bad = read_id(header, "source_id", true, source)) return fail(*bad);
  envelope.source_id = *source;
  if (auto bad = read_id(header, "target_id", false, envelope.target_id)) return fail(*bad);

  const auto type = doc.find("type");
  if (type == doc.end())
    return fail(invalid("/type",
                        "type is required: one of status, task_request, task_response, "
                        "command, negotiation, error"));
  if (!type->is_string()) return fail(invalid("/type", "type must be a string, found " + found(*type)));
  const auto parsed_type = parse_message_type(type->get_ref<const std::string&>());
  if (!parsed_type)
    return fail(invalid("/type", "unknown message type '" + bounded_text(type->get_ref<const std::string&>(), 64) +
                                     "' (known: status, task_request, task_response, command, negotiation, error)"));
  envelope.type = *parsed_type;

  const auto payload = doc.find("payload");
  if (payload == doc.end()) return fail(invalid("/payload", "payload is required: an object"));
  if (!payload->is_object()) return fail(invalid("/payload", "payload must be an object, found " + found(*payload)));
  if (auto fault = check_payload(envelope.type, *payload)) return fail(invalid(fault->field, fault->message));
  envelope.payload = *payload;
  envelope.header_extra = header;
  envelope.received = std::move(doc);
  return envelope;
}

json header_json(const Envelope& envelope) {
  json header = envelope.header_extra.is_object() ? envelope.header_extra : json::object();
  header["version"] = envelope.version;
  header["timestamp"] = envelope.timestamp;
  header["source_id"] = envelope.source_id;
  if (envelope.target_id) header["target_id"] = *envelope.target_id;
  else header.erase("target_id");
  return header;
}

json to_json(const Envelope& envelope) {
  return json{{"header", header_json(envelope)}, {"type", std::string(type_name(envelope.type))}, {"payload", envelope.payload}};
}

std::string serialize(const Envelope& envelope) { return to_json(envelope).dump(-1, ' ', false, json::error_handler_t::replace); }

}  // namespace rcand::r2r_wire
