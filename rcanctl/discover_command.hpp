// `rcanctl discover [--timeout S] [--json]`: browses `_rcan._tcp` through avahi-daemon, resolves every robot, fetches
// its DISCOVER document (GET /api/discovery) and flags any robot whose document disagrees with its TXT record.
#pragma once

#include <iosfwd>
#include <map>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

namespace rcand::rcanctl {

int run_discover(std::span<const std::string> args);
int run_discover(std::span<const std::string> args, std::ostream& out, std::ostream& err);

// Every way a robot's DISCOVER document disagrees with its mDNS advertisement (§9.5): a TXT key missing from or
// different in txt_record, a txt_record key missing from TXT, caps vs capabilities[], status, ruri, name, the port.
std::vector<std::string> discovery_disagreements(const std::map<std::string, std::string>& txt, std::uint16_t port,
                                                 const nlohmann::json& discover);

}  // namespace rcand::rcanctl
