#include "libs/swarm/node_tls.hpp"

namespace rcand::swarm {

std::optional<http::ClientTlsSettings> node_tls_settings(const SwarmNode& node) {
  if (!node.ca) return std::nullopt;
  http::ClientTlsSettings tls;
  tls.ca_file = *node.ca;
  tls.cert_file = node.cert.value_or("");
  tls.key_file = node.key.value_or("");
  tls.ca_setting = "swarm node '" + node.name + "' ca";
  tls.cert_setting = "swarm node '" + node.name + "' cert";
  tls.key_setting = "swarm node '" + node.name + "' key";
  return tls;
}

}  // namespace rcand::swarm
