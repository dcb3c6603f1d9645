#include "libs/rcan/ruri.hpp"

#include <algorithm>
#include <charconv>
#include <vector>

namespace rcand {
namespace {

constexpr std::string_view kScheme = "rcan://";
constexpr std::string_view kWildcard = "*";

bool lower_alnum(char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9'); }
bool hex_digit(char c) { return (c >= 'a' && c <= 'f') || (c >= '0' && c <= '9'); }

bool all_of(std::string_view s, bool (*pred)(char)) { return !s.empty() && std::all_of(s.begin(), s.end(), pred); }

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  for (std::size_t start = 0;;) {
    const std::size_t at = s.find(sep, start);
    parts.push_back(s.substr(start, at == std::string_view::npos ? std::string_view::npos : at - start));
    if (at == std::string_view::npos) return parts;
    start = at + 1;
  }
}

bool valid_name(std::string_view s) {  // manufacturer, model
  return all_of(s, [](char c) { return lower_alnum(c) || c == '-' || c == '_'; });
}
bool valid_registry(std::string_view s) {
  for (std::string_view label : split(s, '.'))
    if (!all_of(label, [](char c) { return lower_alnum(c) || c == '-'; })) return false;
  return true;
}
bool valid_instance(std::string_view s) {
  return all_of(s, [](char c) { return lower_alnum(c) || c == '-'; });
}
bool valid_capability(std::string_view s) {
  return all_of(s, [](char c) { return lower_alnum(c) || c == '-' || c == '_' || c == '.'; }) && s.front() != '.' &&
         s.back() != '.' && s.find("..") == std::string_view::npos;
}
bool valid_device_id(std::string_view s) {
  if (s.size() == 8) return all_of(s, hex_digit);
  if (s.size() != 36) return false;  // UUID: 8-4-4-4-12
  for (std::size_t i = 0; i < s.size(); ++i) {
    const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash ? s[i] != '-' : !hex_digit(s[i])) return false;
  }
  return true;
}

// A segment is valid as itself or, when wildcards are allowed, as a whole '*'.
bool segment_ok(std::string_view s, bool (*valid)(std::string_view), bool wild) { return (wild && s == kWildcard) || valid(s); }

RuriParse fail(std::string error) { return {std::nullopt, std::move(error)}; }

std::string quoted(std::string_view s) {
  // RURIs come from configs and tokens: keep error text short and printable.
  std::string out = "'";
  for (char c : s.substr(0, 80)) out.push_back(c >= 0x20 && c < 0x7f ? c : '?');
  if (s.size() > 80) out += "...";
  return out + "'";
}

}  // namespace

std::string Ruri::to_string() const {
  std::string out(kScheme);
  if (local_form) {
    out += manufacturer + "." + model + "." + device_id;
  } else if (registry == kWildcard && manufacturer == kWildcard && model == kWildcard && device_id == kWildcard && !port &&
             !capability) {
    return out + std::string(kWildcard);
  } else {
    out += registry + "/" + manufacturer + "/" + model + "/" + device_id;
    if (port) out += ":" + std::to_string(*port);
  }
  if (capability) out += "/" + *capability;
  return out;
}

RuriParse parse_ruri(std::string_view text, bool allow_wildcards) {
  const bool wild = allow_wildcards;
  if (wild && (text == kWildcard || text == "rcan://*")) {
    Ruri any;
    any.registry = any.manufacturer = any.model = any.device_id = std::string(kWildcard);
    return {any, {}};
  }
  if (text.size() > 512) return fail("RURI is too long (more than 512 characters)");
  if (!text.starts_with(kScheme)) return fail("RURI " + quoted(text) + " must start with 'rcan://'");
  const std::vector<std::string_view> segments = split(text.substr(kScheme.size()), '/');
  Ruri ruri;

  if (segments.size() == 1 || segments.size() == 2) {  // local shorthand: manufacturer.model.instance[/capability]
    const std::vector<std::string_view> parts = split(segments[0], '.');
    if (parts.size() != 3)
      return fail("RURI " + quoted(text) +
                  ": expected rcan://<manufacturer>.<model>.<instance>[/<capability>] or "
                  "rcan://<registry>/<manufacturer>/<model>/<device-id>[:<port>][/<capability>]");
    if (!segment_ok(parts[0], valid_name, wild))
      return fail("RURI " + quoted(text) + ": manufacturer must be lowercase letters, digits, '-' or '_'");
    if (!segment_ok(parts[1], valid_name, wild))
      return fail("RURI " + quoted(text) + ": model must be lowercase letters, digits, '-' or '_'");
    if (!segment_ok(parts[2], valid_instance, wild))
      return fail("RURI " + quoted(text) + ": instance must be lowercase letters, digits or '-'");
    ruri.registry = std::string(kLocalRegistry);
    ruri.manufacturer = std::string(parts[0]);
    ruri.model = std::string(parts[1]);
    ruri.device_id = std::string(parts[2]);
    ruri.local_form = true;
  } else if (segments.size() == 4 || segments.size() == 5) {
    if (!segment_ok(segments[0], valid_registry, wild))
      return fail("RURI " + quoted(text) + ": registry must be a host name (lowercase letters, digits, '-' and dots)");
    if (!segment_ok(segments[1], valid_name, wild))
      return fail("RURI " + quoted(text) + ": manufacturer must be lowercase letters, digits, '-' or '_'");
    if (!segment_ok(segments[2], valid_name, wild))
      return fail("RURI " + quoted(text) + ": model must be lowercase letters, digits, '-' or '_'");
    std::string_view device = segments[3];
    if (const std::size_t colon = device.find(':'); colon != std::string_view::npos) {
      const std::string_view digits = device.substr(colon + 1);
      unsigned value = 0;
      const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
      if (digits.empty() || digits.size() > 5 || ec != std::errc{} || end != digits.data() + digits.size() || value == 0 ||
          value > 65535)
        return fail("RURI " + quoted(text) + ": port must be a number from 1 to 65535");
      ruri.port = static_cast<std::uint16_t>(value);
      device = device.substr(0, colon);
    }
    if (!segment_ok(device, valid_device_id, wild))
      return fail("RURI " + quoted(text) + ": device-id must be 8 lowercase hex digits or a lowercase UUID");
    ruri.registry = std::string(segments[0]);
    ruri.manufacturer = std::string(segments[1]);
    ruri.model = std::string(segments[2]);
    ruri.device_id = std::string(device);
  } else {
    return fail("RURI " + quoted(text) +
                ": expected rcan://<registry>/<manufacturer>/<model>/<device-id>[:<port>][/<capability>] or "
                "rcan://<manufacturer>.<model>.<instance>[/<capability>]");
  }

  if (segments.size() == 2 || segments.size() == 5) {
    const std::string_view capability = segments.back();
    if (!segment_ok(capability, valid_capability, wild))
      return fail("RURI " + quoted(text) + ": capability must be lowercase letters, digits, '-', '_' or inner dots");
    ruri.capability = std::string(capability);
  }
  return {std::move(ruri), {}};
}

bool ruri_matches(const Ruri& pattern, const Ruri& robot) {
  const auto same = [](const std::string& p, const std::string& r) { return p == kWildcard || p == r; };
  return same(pattern.registry, robot.registry) && same(pattern.manufacturer, robot.manufacturer) &&
         same(pattern.model, robot.model) && same(pattern.device_id, robot.device_id);
}

std::string robot_ruri(const std::optional<std::string>& configured, std::string_view manufacturer, std::string_view model,
                       std::string_view robot_uuid) {
  if (configured && !configured->empty()) return *configured;
  const auto clean = [](std::string_view s) {
    std::string out;
    for (char c : s) {
      if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
      out.push_back(lower_alnum(c) || c == '_' || c == '-' ? c : '-');
    }
    return out.empty() ? std::string("unknown") : out;
  };
  std::string instance;
  for (char c : robot_uuid) {
    if (instance.size() == 8) break;
    if (c >= 'A' && c <= 'F') c = static_cast<char>(c - 'A' + 'a');
    if (hex_digit(c)) instance.push_back(c);  // dashes (and anything else) dropped
  }
  if (instance.empty()) instance = "00000000";
  return std::string(kScheme) + clean(manufacturer) + "." + clean(model) + "." + instance;
}

}  // namespace rcand
