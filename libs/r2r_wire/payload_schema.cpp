#include "libs/r2r_wire/payload_schema.hpp"

#include <cmath>

namespace rcand::r2r_wire {
namespace {

using nlohmann::json;

// One field check: `required` says whether absence is a fault; `nullable` accepts an explicit null.
struct Field {
  const json& payload;
  const char* name;
  std::string pointer() const { return std::string("/payload/") + name; }
  const json* get() const {
    const auto it = payload.find(name);
    return it == payload.end() ? nullptr : &*it;
  }
};

PayloadFault fault(const Field& f, std::string message) { return {f.pointer(), std::string(f.name) + " " + std::move(message)}; }

std::optional<PayloadFault> string_field(const json& payload, const char* name, bool required, bool non_empty) {
  const Field f{payload, name};
  const json* v = f.get();
  if (v == nullptr) return required ? std::optional(fault(f, "is required: a string")) : std::nullopt;
  if (!v->is_string()) return fault(f, std::string("must be a string, found ") + v->type_name());
  if (non_empty && v->get_ref<const std::string&>().empty()) return fault(f, "must not be empty");
  return std::nullopt;
}

std::optional<PayloadFault> number_field(const json& payload, const char* name, bool required, bool nullable,
                                         std::optional<double> min = std::nullopt, std::optional<double> max = std::nullopt) {
  const Field f{payload, name};
  const json* v = f.get();
  if (v == nullptr) return required ? std::optional(fault(f, "is required: a number")) : std::nullopt;
  if (v->is_null() && nullable) return std::nullopt;
  if (!v->is_number() || v->is_boolean()) return fault(f, std::string("must be a number, found ") + v->type_name());
  const double d = v->get<double>();
  if (!std::isfinite(d)) return fault(f, "must be a finite number");
  if (min && d < *min) return fault(f, "must be >= " + json(*min).dump());
  if (max && d > *max) return fault(f, "must be <= " + json(*max).dump());
  return std::nullopt;
}

std::optional<PayloadFault> bool_field(const json& payload, const char* name, bool required) {
  const Field f{payload, name};
  const json* v = f.get();
  if (v == nullptr) return required ? std::optional(fault(f, "is required: true or false")) : std::nullopt;
  if (!v->is_boolean()) return fault(f, std::string("must be true or false, found ") + v->type_name());
  return std::nullopt;
}

std::optional<PayloadFault> string_array_field(const json& payload, const char* name, bool required) {
  const Field f{payload, name};
  const json* v = f.get();
  if (v == nullptr) return required ? std::optional(fault(f, "is required: an array of strings")) : std::nullopt;
  if (!v->is_array()) return fault(f, std::string("must be an array of strings, found ") + v->type_name());
  for (std::size_t i = 0; i < v->size(); ++i)
    if (!(*v)[i].is_string() || (*v)[i].get_ref<const std::string&>().empty())
      return PayloadFault{f.pointer() + "/" + std::to_string(i), std::string(name) + " must contain only non-empty strings"};
  return std::nullopt;
}

// {"x","y"} (and "heading_deg" when with_heading), finite numbers; `nullable` accepts null.
std::optional<PayloadFault> point_field(const json& payload, const char* name, bool with_heading, bool nullable) {
  const Field f{payload, name};
  const json* v = f.get();
  if (v == nullptr || (v->is_null() && nullable)) return std::nullopt;
  if (!v->is_object()) return fault(f, std::string("must be an object {\"x\",\"y\"}, found ") + v->type_name());
  for (const char* axis : {"x", "y", "heading_deg"}) {
    const bool required = std::string_view(axis) != "heading_deg";
    if (!required && !with_heading) continue;
    if (auto bad = number_field(*v, axis, required, false))
      return PayloadFault{f.pointer() + "/" + axis, std::string(name) + "." + bad->message};
  }
  return std::nullopt;
}

std::optional<PayloadFault> first(std::initializer_list<std::optional<PayloadFault>> checks) {
  for (const auto& check : checks)
    if (check) return check;
  return std::nullopt;
}

std::optional<PayloadFault> check_status(const json& p) {
  return first({number_field(p, "battery", false, true, 0.0, 100.0), point_field(p, "position", true, true),
                number_field(p, "task_progress", false, true, 0.0, 1.0), string_field(p, "state", false, false),
                bool_field(p, "estopped", false), string_array_field(p, "capabilities", false)});
}

std::optional<PayloadFault> check_task_request(const json& p) {
  return first({string_field(p, "task_id", true, true), string_field(p, "description", false, false),
                number_field(p, "deadline", false, false, 0.0), string_array_field(p, "required_capabilities", false),
                point_field(p, "location", false, false), number_field(p, "bid_deadline", false, false, 0.0)});
}

std::optional<PayloadFault> check_task_response(const json& p) {
  return first({string_field(p, "task_id", true, true), bool_field(p, "accepted", true),
                number_field(p, "estimated_time", false, true, 0.0), string_field(p, "reason", false, false)});
}

std::optional<PayloadFault> check_negotiation(const json& p) {
  if (auto bad = first({string_field(p, "task_id", true, true), string_field(p, "action", true, true)})) return bad;
  const std::string& action = p["action"].get_ref<const std::string&>();
  if (action == "bid") return first({number_field(p, "cost", true, false, 0.0), string_array_field(p, "capabilities", false)});
  if (action == "award" || action == "withdraw") return std::nullopt;
  return PayloadFault{"/payload/action", "action must be bid, award or withdraw, found '" + action + "'"};
}

std::optional<PayloadFault> check_command(const json& p) {
  // The body of POST /api/action: the kernel's action route validates the rest exactly as over HTTP. The fleet
  // e-stop is not an action: its only other field is checked here.
  if (auto bad = string_field(p, "type", true, true)) return bad;
  if (p["type"] == "estop") return string_field(p, "reason", false, false);
  return std::nullopt;
}

std::optional<PayloadFault> check_error(const json& p) {
  const Field code{p, "code"};
  const json* v = code.get();
  if (v == nullptr) return fault(code, "is required: an integer");
  if (!v->is_number_integer()) return fault(code, std::string("must be an integer, found ") + v->type_name());
  if (auto bad = string_field(p, "message", true, false)) return bad;
  if (const auto ref = p.find("ref"); ref != p.end() && !ref->is_null() && !ref->is_object())
    return PayloadFault{"/payload/ref", std::string("ref must be an object (the header answered), found ") + ref->type_name()};
  return std::nullopt;
}

}  // namespace

bool is_fleet_estop(MessageType type, const nlohmann::json& payload) noexcept {
  if (type != MessageType::Command || !payload.is_object()) return false;
  const auto it = payload.find("type");
  return it != payload.end() && it->is_string() && it->get_ref<const std::string&>() == "estop";
}

std::optional<PayloadFault> check_payload(MessageType type, const nlohmann::json& payload) {
  switch (type) {
    case MessageType::Status: return check_status(payload);
    case MessageType::TaskRequest: return check_task_request(payload);
    case MessageType::TaskResponse: return check_task_response(payload);
    case MessageType::Command: return check_command(payload);
    case MessageType::Negotiation: return check_negotiation(payload);
    case MessageType::Error: return check_error(payload);
  }
  return PayloadFault{"/type", "unknown message type"};
}

}  // namespace rcand::r2r_wire
