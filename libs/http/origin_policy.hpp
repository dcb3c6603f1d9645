// Which browser pages may use the robot (docs/protocol.md §3.9). A browser marks its requests: an `Origin` header on
// every request a page makes other than a same-origin GET, and on every WebSocket upgrade (`Sec-Fetch-Site` too, where
// the page is a secure context). curl, rcanctl and robots send neither, and the origin part of this rule never
// touches them. A browser's request is allowed when:
//   - its Origin is listed in runtime.listen.allowed_origins; or
//   - its Origin is the robot's own, i.e. the page was served by the robot: same scheme as the connection and the
//     same host:port as the Host header the browser sent, and (over plain HTTP) that host is a name the robot knows:
//     an IP address, localhost or *.localhost, the machine's host name or <host name>.local,
//     <metadata.robot_name>.local, or the host of an allowed origin. The name check defeats DNS rebinding: a page of
//     evil.example whose name later resolves to the robot is same-origin by host:port, but the name is not the
//     robot's. Over TLS the certificate already proves the name belongs to the robot;
//   - it has no Origin (a same-origin GET, a navigation, an <img>) and its Host passes the same name check.
// `Origin: null` (sandboxed frames, file:// pages) is never the robot's own, and cannot be listed. A rebinding page's
// same-origin GETs carry neither mark over plain HTTP, so in auth mode open (where a GET needs no credential) every
// request's Host must pass the name check, marked or not.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "libs/http/request.hpp"
#include "libs/rcan/web_origin.hpp"

namespace rcand::http {

struct OriginPolicySettings {
  std::vector<std::string> allowed_origins;  // runtime.listen.allowed_origins, as written ("https://fleet.example.com")
  std::vector<std::string> own_names;        // the robot's DNS names besides localhost (own_host_names())
};

class OriginPolicy {
 public:
  // Throws std::invalid_argument naming an allowed origin that does not parse (the config schema refuses it first).
  explicit OriginPolicy(OriginPolicySettings settings = {});

  struct Refusal {
    std::string message;  // for people: what was refused and how to allow it
    std::string origin;   // the Origin header as sent (empty when there was none)
  };
  // nullopt: the request may go on. `every_host`: check the Host of requests without browser marks too (auth mode
  // open). Any thread; no allocation for a request without Origin or Sec-Fetch-Site unless `every_host`.
  std::optional<Refusal> check(const Request& request, bool every_host = false) const;

  // The names this machine answers to on the local network: its host name, <host name>.local, and
  // <robot_name>.local when robot_name is a valid DNS label (lower case).
  static std::vector<std::string> own_host_names(std::string_view robot_name);

 private:
  bool known_name(const WebAuthority& host) const;
  bool listed(const WebOrigin& origin) const;

  std::vector<WebOrigin> allowed_;
  std::vector<std::string> names_;  // own_names and the allowed origins' hosts, lower case
};

}  // namespace rcand::http
