// A robot identity for installs whose config gives none: every board shipped with the same packaged config would
// otherwise be the same robot (rcan://rcand.sim-rover.00000000). Derived from /etc/machine-id the way systemd asks
// applications to (an HMAC keyed by the machine id, so the id itself is never exposed): stable across upgrades and
// reinstalls on one machine, different on every other.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace rcand {

// A version-4-shaped UUID ("xxxxxxxx-xxxx-4xxx-8xxx-xxxxxxxxxxxx"); nullopt when `machine_id_file` is missing or
// does not hold 32 hex digits.
std::optional<std::string> robot_uuid_from_machine_id(const std::filesystem::path& machine_id_file = "/etc/machine-id");

// The placeholders configs ship with (all zeros, with or without the version and variant digits): not an identity.
bool is_placeholder_uuid(std::string_view uuid) noexcept;

}  // namespace rcand
