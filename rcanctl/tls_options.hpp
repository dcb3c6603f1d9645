// How rcanctl reaches a robot that serves TLS (runtime.listen.tls): `--host https://robot.local[:PORT]`, or --cacert
// FILE (the CA the robot's certificate must chain to; else the system's trust store), and --cert/--key for mutual
// TLS. $RCAND_CACERT, $RCAND_CERT and $RCAND_KEY supply the files when the options are not given; they do not turn
// TLS on by themselves (so `rcanctl status` keeps reaching the plain loopback port). The robot's certificate must
// name the host given (a .local name is checked as the name, not as the address it resolved to).
#pragma once

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

inline constexpr const char* kTlsOptionsUsage =
    "  TLS: --host https://HOST[:PORT], or --cacert FILE (the CA that signed the robot's certificate; default the\n"
    "  system's CAs), --cert FILE --key FILE for mutual TLS ($RCAND_CACERT, $RCAND_CERT, $RCAND_KEY supply them).\n";

// --cacert, --cert or --key: takes its value through `next` and returns true (`ok` false when the value is missing);
// false for any other option.
bool parse_tls_option(const std::string& option, const std::function<bool(std::string&)>& next, TlsOptions& tls, bool& ok);

// After the options: splits a scheme (and port) off `host` ("https://alex.local:8443"), fills the files from the
// environment. An error message ("--host: ...") or "".
std::string finish_tls_options(TlsOptions& tls, std::string& host, std::uint16_t& port);

// The client settings for `host`, or nullopt without TLS.
std::optional<http::ClientTlsSettings> client_tls(const TlsOptions& tls, const std::string& host);

// A one-robot target's TLS as a swarm node carries it (for the fan-out): `ca` engaged (empty: the system's CAs).
void apply_tls(const TlsOptions& tls, swarm::SwarmNode& node);

}  // namespace rcand::rcanctl
