#include "tls_options.hpp"

#include <cstdlib>

#include "robot_connection.hpp"

namespace rcand::rcanctl {

bool parse_tls_option(const std::string& option, const std::function<bool(std::string&)>& next, TlsOptions& tls, bool& ok) {
  std::string* into = option == "--cacert" ? &tls.ca_file
                      : option == "--cert" ? &tls.cert_file
                      : option == "--key"  ? &tls.key_file
                                           : nullptr;
  if (into == nullptr) return false;
  ok = next(*into);
  if (ok && option != "--key") tls.https = true;
  return true;
}

std::string finish_tls_options(TlsOptions& tls, std::string& host, std::uint16_t& port) {
  for (const std::string scheme : {"https://", "http://"}) {
    if (host.rfind(scheme, 0) != 0) continue;
    std::string rest = host.substr(scheme.size());
    if (const auto slash = rest.find('/'); slash != std::string::npos) rest.resize(slash);
    // "[::1]:8443", "alex.local:8443", "10.0.0.2"
    const bool bracketed = !rest.empty() && rest.front() == '[';
    const auto colon = rest.rfind(':');
    const bool has_port =
        colon != std::string::npos && (bracketed ? colon > rest.rfind(']') : rest.find(':') == colon);  // a bare IPv6 has no port
    if (has_port) {
      const auto parsed = parse_int(rest.substr(colon + 1), 1, 65535);
      if (!parsed) return "--host: bad port in '" + host + "'";
      port = static_cast<std::uint16_t>(*parsed);
      rest.resize(colon);
    }
    if (rest.size() > 2 && rest.front() == '[' && rest.back() == ']') rest = rest.substr(1, rest.size() - 2);
    if (rest.empty()) return "--host: no host name in '" + host + "'";
    if (scheme == "https://") tls.https = true;
    else if (tls.https) return "--host: http:// with --cacert/--cert: use https://";
    host = rest;
    break;
  }
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
