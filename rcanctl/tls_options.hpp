// How rcanctl reaches a robot that serves TLS (runtime.listen.tls): `--host https://robot.local[:PORT]`, or --cacert
// FILE (the CA the robot's certificate must chain to; else the system's trust store), and --cert/--key for mutual
// TLS. $RCAND_CACERT, $RCAND_CERT and $RCAND_KEY supply the files when the options are not given; they do not turn
// TLS on by themselves (so `rcanctl status` keeps reaching the plain loopback port). The robot's certificate must
// name the host given (a .local name is checked as the name, not as the address it resolved to).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "libs/http/tls_settings.hpp"
#include "libs/swarm/swarm_registry.hpp"

namespace rcand::rcanctl {

struct TlsOptions {
  bool https = false;  // an https:// host, --cacert or --cert
  std::string ca_file, cert_file, key_file;
};

// Declares --cacert, --cert and --key on `app` (into `tls`).
void add_tls_options(CLI::App& app, TlsOptions& tls);

// After the options: splits a scheme and a port off `host` ("https://alex.local:8443", "127.0.0.1:8000"), fills the
// files from the environment. An error message ("--host: ...") or "".
std::string finish_tls_options(TlsOptions& tls, std::string& host, std::uint16_t& port);
// The files from the environment ($RCAND_CACERT, ...) and their consistency check; part of finish_tls_options.
std::string finish_tls_files(TlsOptions& tls);

// The client settings for `host`, or nullopt without TLS.
std::optional<http::ClientTlsSettings> client_tls(const TlsOptions& tls, const std::string& host);

// A one-robot target's TLS as a swarm node carries it (for the fan-out): `ca` engaged (empty: the system's CAs).
void apply_tls(const TlsOptions& tls, swarm::SwarmNode& node);

}  // namespace rcand::rcanctl
