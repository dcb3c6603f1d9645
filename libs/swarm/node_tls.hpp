// How this robot reaches a swarm node over TLS (swarm.yaml `ca`, `cert`, `key`): one reading of a node's entry, so
// the §15 fan-out (HTTPS) and R2R's WebSocket dialer (wss) trust the same files and name them the same way.
#pragma once

#include <optional>

#include "libs/http/tls_settings.hpp"
#include "libs/swarm/swarm_registry.hpp"

namespace rcand::swarm {

// The client settings for a node with `ca` (its certificate must chain to that file and name its host; `cert`/`key`
// for mutual TLS); nullopt for a node reached in plain text.
std::optional<http::ClientTlsSettings> node_tls_settings(const SwarmNode& node);

}  // namespace rcand::swarm
