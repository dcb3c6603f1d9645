// TLS contexts (OpenSSL through Boost.Asio) for the server (runtime.listen.tls) and for the clients that reach it
// (rcanctl, the swarm fan-out, tests), with the one policy both sides share: TLS 1.2 or later, forward-secret AEAD
// ciphers only, peers verified against a named CA file, host names checked. Every problem is a TlsError whose message
// names the setting and the file, never a key's bytes.
#pragma once

#include <boost/asio/ssl/context.hpp>
#include <boost/system/error_code.hpp>

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "libs/http/tls_settings.hpp"

namespace rcand::http {

class TlsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The server's context: the certificate chain and key of `settings` (the key must match the certificate and must not
// be readable by other users), and with client_ca_file a client certificate required and verified against it.
// An expired or not-yet-valid certificate is only logged: a robot without a clock battery boots in 1970.
std::shared_ptr<boost::asio::ssl::context> make_server_tls_context(const TlsSettings& settings);

// A client's context: peers verified against ca_file (or the system's CAs), its certificate for mutual TLS.
std::shared_ptr<boost::asio::ssl::context> make_client_tls_context(const ClientTlsSettings& settings);

// Before a client handshake: SNI for a name, and the name or IP address the server's certificate must carry.
void expect_server_name(SSL* ssl, const std::string& host);

// Why a TLS handshake failed, for a message: the certificate check's verdict when that was the cause
// ("certificate verify failed: certificate has expired"), else the error's own text.
std::string tls_failure(SSL* ssl, const boost::system::error_code& ec);

// A private key file's permissions, like ssh's: "" when no other user may read or write it, else the complaint.
std::string key_permission_problem(const std::filesystem::path& key_file);

}  // namespace rcand::http
