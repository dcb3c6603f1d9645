// Robot URIs (docs/protocol.md §1): the canonical form
// rcan://<registry>/<manufacturer>/<model>/<device-id>[:<port>][/<capability>] and the local shorthand
// rcan://<manufacturer>.<model>.<instance>[/<capability>] (registry "local.rcan"), one parser.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace rcand {

struct Ruri {
  std::string registry, manufacturer, model, device_id;  // local form: registry "local.rcan", device_id = instance
  std::optional<std::uint16_t> port;
  std::optional<std::string> capability;
  bool local_form = false;
  std::string to_string() const;  // canonical form as written (local form stays local)
};

struct RuriParse {
  std::optional<Ruri> ruri;
  std::string error;  // set when ruri is empty; names the part at fault
};

inline constexpr std::string_view kLocalRegistry = "local.rcan";

// Segments are lowercase: registry = dot-separated [a-z0-9-] labels, manufacturer/model = [a-z0-9_-]+, capability =
// [a-z0-9_.-]+ (reverse-domain names such as com.acme.gripper). The canonical device-id is 8 lowercase hex digits or a
// lowercase UUID; the local form's instance is any [a-z0-9-]+. allow_wildcards: '*' may be a whole segment (only for
// JWT aud matching), and "*" or "rcan://*" alone mean every robot.
RuriParse parse_ruri(std::string_view text, bool allow_wildcards = false);

// `pattern` may hold '*' segments; "rcan://*" and "*" match every robot. Compares registry, manufacturer, model and
// device_id (so a local-form pattern matches the same robot written canonically); port and capability are ignored.
bool ruri_matches(const Ruri& pattern, const Ruri& robot);

// metadata.ruri when given, else rcan://<manufacturer>.<model>.<first 8 hex of robot_uuid, lowercase, dashes removed>.
// Manufacturer and model are lowercased and any character outside [a-z0-9_-] becomes '-', so the result always parses
// (a uuid with no hex digit at all gives instance "00000000"; the config module is expected to validate it).
std::string robot_ruri(const std::optional<std::string>& configured, std::string_view manufacturer, std::string_view model,
                       std::string_view robot_uuid);

}  // namespace rcand
