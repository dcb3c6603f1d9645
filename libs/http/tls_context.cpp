#include "libs/http/tls_context.hpp"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509v3.h>

#include <boost/asio/ip/address.hpp>
#include <boost/asio/ssl/error.hpp>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "libs/base/file_exposure.hpp"
#include "libs/http/http_logger.hpp"

namespace rcand::http {

namespace ssl = boost::asio::ssl;

namespace {

// TLS 1.2 suites with forward secrecy and an AEAD cipher only; TLS 1.3's own suites are all of that kind already.
constexpr const char* kTls12Ciphers = "ECDHE+AESGCM:ECDHE+CHACHA20:!aNULL:!eNULL";
constexpr unsigned char kSessionContext[] = "rcand";

std::string quoted(const std::string& setting, const std::filesystem::path& file) { return setting + " '" + file.string() + "'"; }

// The queued OpenSSL errors as one line (then cleared), for the "(...)" part of a message.
std::string openssl_errors() {
  std::string text;
  while (const unsigned long code = ERR_get_error()) {
    char line[256];
    ERR_error_string_n(code, line, sizeof line);
    text += (text.empty() ? "" : "; ") + std::string(line);
  }
  return text.empty() ? "no detail from OpenSSL" : text;
}

// A clear "cannot read" before OpenSSL, whose own message for a missing file is "system lib".
void require_readable(const std::filesystem::path& file, const std::string& name) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) throw TlsError(name + ": is a directory, not a PEM file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw TlsError(name + ": cannot read: " + std::strerror(errno));
  if (in.peek() == std::ifstream::traits_type::eof()) throw TlsError(name + ": the file is empty");
}

// Never prompt on the terminal for an encrypted key's passphrase: it fails instead, with a message.
int no_passphrase(char*, int, int, void*) { return 0; }

void apply_policy(ssl::context& context) {
  SSL_CTX* ctx = context.native_handle();
  context.set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                      ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 | ssl::context::no_compression);
  SSL_CTX_set_options(ctx, SSL_OP_NO_RENEGOTIATION | SSL_OP_CIPHER_SERVER_PREFERENCE);
  if (SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION) != 1 || SSL_CTX_set_cipher_list(ctx, kTls12Ciphers) != 1)
    throw TlsError("cannot set the TLS policy: " + openssl_errors());
  SSL_CTX_set_default_passwd_cb(ctx, no_passphrase);
}

void use_certificate_and_key(SSL_CTX* ctx, const std::filesystem::path& cert_file, const std::string& cert_name,
                             const std::filesystem::path& key_file, const std::string& key_name) {
  require_readable(cert_file, cert_name);
  require_readable(key_file, key_name);
  if (auto problem = key_permission_problem(key_file); !problem.empty()) throw TlsError(key_name + ": " + problem);
  ERR_clear_error();
  if (SSL_CTX_use_certificate_chain_file(ctx, cert_file.c_str()) != 1)
    throw TlsError(cert_name + ": not a PEM certificate (chain): " + openssl_errors());
  if (SSL_CTX_use_PrivateKey_file(ctx, key_file.c_str(), SSL_FILETYPE_PEM) != 1) {
    // OpenSSL compares a key with the certificate already loaded as it takes it.
    const unsigned long code = ERR_peek_last_error();
    const bool mismatch = ERR_GET_LIB(code) == ERR_LIB_X509 && (ERR_GET_REASON(code) == X509_R_KEY_VALUES_MISMATCH ||
                                                                ERR_GET_REASON(code) == X509_R_KEY_TYPE_MISMATCH);
    if (mismatch) {
      ERR_clear_error();
      throw TlsError(key_name + " does not match the certificate in " + cert_name);
    }
    throw TlsError(key_name + ": not a PEM private key, or one encrypted with a passphrase: " + openssl_errors());
  }
  if (SSL_CTX_check_private_key(ctx) != 1) {
    ERR_clear_error();
    throw TlsError(key_name + " does not match the certificate in " + cert_name);
  }
}

void trust_ca_file(SSL_CTX* ctx, const std::filesystem::path& ca_file, const std::string& ca_name) {
  require_readable(ca_file, ca_name);
  ERR_clear_error();
  if (SSL_CTX_load_verify_locations(ctx, ca_file.c_str(), nullptr) != 1)
    throw TlsError(ca_name + ": not a PEM CA certificate: " + openssl_errors());
}

void warn_when_out_of_date(SSL_CTX* ctx, const std::string& cert_name) {
  X509* leaf = SSL_CTX_get0_certificate(ctx);
  if (leaf == nullptr) return;
  if (X509_cmp_current_time(X509_get0_notAfter(leaf)) < 0)
    detail::http_logger()->warn("{}: the certificate has expired: clients will refuse it (or this robot's clock is wrong)",
                                cert_name);
  else if (X509_cmp_current_time(X509_get0_notBefore(leaf)) > 0)
    detail::http_logger()->warn("{}: the certificate is not valid yet: clients will refuse it (or this robot's clock is wrong)",
                                cert_name);
}

}  // namespace

std::string key_permission_problem(const std::filesystem::path& key_file) {
  return others_may_access(key_file, "this private key");
}

std::shared_ptr<ssl::context> make_server_tls_context(const TlsSettings& settings) {
  const std::string cert_name = quoted(settings.setting + ".cert_file", settings.cert_file);
  const std::string key_name = quoted(settings.setting + ".key_file", settings.key_file);
  auto context = std::make_shared<ssl::context>(ssl::context::tls_server);
  apply_policy(*context);
  SSL_CTX* ctx = context->native_handle();
  use_certificate_and_key(ctx, settings.cert_file, cert_name, settings.key_file, key_name);
  warn_when_out_of_date(ctx, cert_name);
  // Resumed sessions need a context id once peers are verified (else OpenSSL refuses to resume them).
  SSL_CTX_set_session_id_context(ctx, kSessionContext, sizeof kSessionContext - 1);
  if (settings.client_ca_file) {
    const std::string ca_name = quoted(settings.setting + ".client_ca_file", *settings.client_ca_file);
    trust_ca_file(ctx, *settings.client_ca_file, ca_name);
    STACK_OF(X509_NAME)* names = SSL_load_client_CA_file(settings.client_ca_file->c_str());
    if (names == nullptr) throw TlsError(ca_name + ": no CA certificate in it: " + openssl_errors());
    SSL_CTX_set_client_CA_list(ctx, names);  // what the server asks for, so a client can pick its certificate
    SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER | SSL_VERIFY_FAIL_IF_NO_PEER_CERT, nullptr);
  }
  return context;
}

std::shared_ptr<ssl::context> make_client_tls_context(const ClientTlsSettings& settings) {
  auto context = std::make_shared<ssl::context>(ssl::context::tls_client);
  apply_policy(*context);
  SSL_CTX* ctx = context->native_handle();
  if (settings.ca_file.empty()) {
    if (SSL_CTX_set_default_verify_paths(ctx) != 1) throw TlsError("cannot load the system's trusted CAs: " + openssl_errors());
  } else {
    trust_ca_file(ctx, settings.ca_file, quoted(settings.ca_setting, settings.ca_file));
  }
  SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER, nullptr);
  if (!settings.cert_file.empty()) {
    const auto& key_file = settings.key_file.empty() ? settings.cert_file : settings.key_file;
    use_certificate_and_key(ctx, settings.cert_file, quoted(settings.cert_setting, settings.cert_file), key_file,
                            quoted(settings.key_setting, key_file));
  } else if (!settings.key_file.empty()) {
    throw TlsError(quoted(settings.key_setting, settings.key_file) + " is given without a " + settings.cert_setting);
  }
  return context;
}

void expect_server_name(SSL* ssl, const std::string& host) {
  boost::system::error_code ec;
  boost::asio::ip::make_address(host, ec);
  const bool named = static_cast<bool>(ec);
  const bool ok = named ? SSL_set_tlsext_host_name(ssl, host.c_str()) == 1 && SSL_set1_host(ssl, host.c_str()) == 1
                        : X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(ssl), host.c_str()) == 1;
  if (!ok) throw TlsError("cannot check the server's certificate against '" + host + "': " + openssl_errors());
}

std::string tls_failure(SSL* ssl, const boost::system::error_code& ec) {
  const long verdict = ssl != nullptr ? SSL_get_verify_result(ssl) : X509_V_OK;
  if (verdict != X509_V_OK) {
    std::string text = std::string("certificate verify failed: ") + X509_verify_cert_error_string(verdict);
    if (verdict == X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT_LOCALLY || verdict == X509_V_ERR_SELF_SIGNED_CERT_IN_CHAIN ||
        verdict == X509_V_ERR_DEPTH_ZERO_SELF_SIGNED_CERT || verdict == X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT)
      text += " (the server's certificate is not signed by the CA this client trusts)";
    else if (verdict == X509_V_ERR_HOSTNAME_MISMATCH || verdict == X509_V_ERR_IP_ADDRESS_MISMATCH)
      text += " (the certificate does not name the host connected to)";
    return text;
  }
  if (ec.category() == boost::asio::error::get_ssl_category()) {
    const int reason = ERR_GET_REASON(static_cast<unsigned long>(ec.value()));
    if (reason == SSL_R_TLSV13_ALERT_CERTIFICATE_REQUIRED || reason == SSL_R_SSLV3_ALERT_HANDSHAKE_FAILURE ||
        reason == SSL_R_SSLV3_ALERT_BAD_CERTIFICATE)
      return ec.message() + " (the server refused the handshake: it may require a client certificate it trusts)";
    if (reason == SSL_R_WRONG_VERSION_NUMBER || reason == SSL_R_PACKET_LENGTH_TOO_LONG)
      return ec.message() + " (the server does not speak TLS on this port: try http://)";
  }
  if (ec == boost::asio::ssl::error::stream_truncated) return "the server closed the TLS connection without a close_notify";
  return ec.message();
}

}  // namespace rcand::http
