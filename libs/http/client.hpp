// A small blocking HTTP/1.1 client (rcanctl, tests): one keep-alive connection per Client, plain or TLS.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "libs/http/tls_settings.hpp"

namespace rcand::http {

struct ClientResponse {
  int status = 0;
  std::string body;
  std::map<std::string, std::string> headers;  // names lower-cased; repeated headers joined with ", "
};

// Messages: "cannot connect to 127.0.0.1:8000: Connection refused", "cannot resolve host 'x': ...",
// "GET /api/status on 127.0.0.1:8000: timed out after 500 ms", "GET /x on 127.0.0.1:8000: bad response: ...",
// "TLS handshake with 127.0.0.1:8443 failed: certificate verify failed: certificate has expired" (nothing was sent),
// "--cacert 'ca.pem': cannot read: No such file or directory".
class ClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Not thread-safe: one request at a time per Client. Reconnects when the server closed the kept-alive connection
// (a request that failed on a reused connection before any byte of the answer arrived is sent once more).
class Client {
 public:
  // `tls` set: HTTPS, the server's certificate verified (libs/http/tls_context.hpp); its files are read here
  // (ClientError when they cannot be used).
  Client(std::string host, std::uint16_t port, std::chrono::milliseconds timeout = std::chrono::milliseconds{5000},
         std::optional<ClientTlsSettings> tls = std::nullopt);
  ~Client();
  Client(Client&&) noexcept;
  Client& operator=(Client&&) noexcept;

  // `timeout` bounds the whole exchange (resolve, connect, send, receive). Adds Host, User-Agent and, for a non-empty
  // body without one, "Content-Type: application/json". Throws ClientError.
  ClientResponse request(std::string_view method, std::string_view target, std::string_view body = {},
                         const std::map<std::string, std::string>& headers = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One request on a fresh connection (sent with "Connection: close").
ClientResponse request(const std::string& host, std::uint16_t port, std::string_view method, std::string_view target,
                       std::string_view body = {}, const std::map<std::string, std::string>& headers = {},
                       std::chrono::milliseconds timeout = std::chrono::milliseconds{5000},
                       std::optional<ClientTlsSettings> tls = std::nullopt);

}  // namespace rcand::http
