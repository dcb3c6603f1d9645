// What TLS uses on either side, as plain settings (no OpenSSL here): the server's files (runtime.listen.tls) and a
// client's trust and certificate (rcanctl --cacert/--cert/--key, swarm.yaml `ca`). libs/http/tls_context.hpp turns
// them into OpenSSL contexts.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace rcand::http {

struct TlsSettings {
  std::filesystem::path cert_file;                      // the certificate chain, leaf first
  std::filesystem::path key_file;                       // its private key: no access for other users (mode 600/640)
  std::optional<std::filesystem::path> client_ca_file;  // set: mutual TLS, a certificate it signed is required
  std::string setting = "runtime.listen.tls";           // how messages name these settings
};

struct ClientTlsSettings {
  std::filesystem::path ca_file;    // the CA the server's certificate must chain to; empty: the system's trust store
  std::filesystem::path cert_file;  // mutual TLS: this client's certificate chain; empty: none
  std::filesystem::path key_file;   // its key; empty: in cert_file
  // The name the server's certificate must carry (and SNI) when the host connected to is an address found for it
  // (a .local name resolved beforehand); empty: the host connected to.
  std::string server_name;
  // How messages name the files ("--cacert", "swarm.yaml nodes[2].ca").
  std::string ca_setting = "CA file", cert_setting = "client certificate", key_setting = "client key";
};

}  // namespace rcand::http
