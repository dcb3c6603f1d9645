#include "tls_options.hpp"

#include <cstdlib>

#include "robot_connection.hpp"

namespace rcand::rcanctl {

void add_tls_options(CLI::App& app, TlsOptions& tls) {
  const auto file = [&tls](std::string& into, bool https) {
    return [&tls, &into, https](const std::string& value) {
      into = value;
      tls.https = tls.https || https;  // --key alone turns nothing on: it goes with --cert
    };
  };
  app.add_option_function<std::string>("--cacert", file(tls.ca_file, true),
                                       "TLS: the CA that signed the robot's certificate (default the system's; $RCAND_CACERT)");
  app.add_option_function<std::string>("--cert", file(tls.cert_file, true),
                                       "TLS: a client certificate for mutual TLS ($RCAND_CERT)");
  app.add_option_function<std::string>("--key", file(tls.key_file, false), "TLS: the client certificate's key ($RCAND_KEY)");
}

namespace {

// "[::1]:8443", "alex.local:8443", "10.0.0.2" (a bare IPv6 address has no port): the port into `port`, `name`
// without it or the brackets. An error message or "".
std::string split_host_port(std::string& name, std::uint16_t& port, const std::string& given) {
  const bool bracketed = !name.empty() && name.front() == '[';
  const auto colon = name.rfind(':');
  if (colon != std::string::npos && (bracketed ? colon > name.rfind(']') : name.find(':') == colon)) {
    const auto parsed = parse_int(name.substr(colon + 1), 1, 65535);
    if (!parsed) return "--host: bad port in '" + given + "' (HOST:PORT, PORT from 1 to 65535)";
    port = static_cast<std::uint16_t>(*parsed);
    name.resize(colon);
  }
  if (name.size() > 2 && name.front() == '[' && name.back() == ']') name = name.substr(1, name.size() - 2);
  if (name.empty()) return "--host: no host name in '" + given + "'";
  return {};
}

}  // namespace

std::string finish_tls_options(TlsOptions& tls, std::string& host, std::uint16_t& port) {
  std::string name = host;
  for (const std::string scheme : {"https://", "http://"}) {
    if (host.rfind(scheme, 0) != 0) continue;
    name = host.substr(scheme.size());
    if (const auto slash = name.find('/'); slash != std::string::npos) name.resize(slash);
    if (scheme == "https://") tls.https = true;
    else if (tls.https) return "--host: http:// with --cacert/--cert: use https://";
  }
  if (auto problem = split_host_port(name, port, host); !problem.empty()) return problem;
  host = name;
  return finish_tls_files(tls);
}

std::string finish_tls_files(TlsOptions& tls) {
  const auto from_env = [](std::string& value, const char* name) {
    if (const char* env = std::getenv(name); value.empty() && env != nullptr) value = env;
  };
  from_env(tls.ca_file, "RCAND_CACERT");
  from_env(tls.cert_file, "RCAND_CERT");
  from_env(tls.key_file, "RCAND_KEY");
  if (tls.https && !tls.key_file.empty() && tls.cert_file.empty()) return "--key is given without --cert";
  return {};
}

std::optional<http::ClientTlsSettings> client_tls(const TlsOptions& tls, const std::string& host) {
  if (!tls.https) return std::nullopt;
  http::ClientTlsSettings settings;
  settings.ca_file = tls.ca_file;
  settings.cert_file = tls.cert_file;
  settings.key_file = tls.key_file;
  settings.server_name = host;
  settings.ca_setting = "--cacert";
  settings.cert_setting = "--cert";
  settings.key_setting = "--key";
  return settings;
}

void apply_tls(const TlsOptions& tls, swarm::SwarmNode& node) {
  if (!tls.https) return;
  node.ca = tls.ca_file;
  if (!tls.cert_file.empty()) node.cert = tls.cert_file;
  if (!tls.key_file.empty()) node.key = tls.key_file;
}

}  // namespace rcand::rcanctl
