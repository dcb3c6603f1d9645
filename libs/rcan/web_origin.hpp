// Web origins (RFC 6454: scheme://host[:port]) and the Host header's authority (RFC 9110 §7.2), parsed so that rcand
// can compare a browser page's origin with the robot's own (docs/protocol.md §3.9). Strict: what a browser sends
// parses; a path, user info, a query, another scheme or the opaque origin "null" does not.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace rcand {

struct WebAuthority {
  std::string host;         // lower case, without a trailing dot; an IPv6 address without its brackets
  std::uint16_t port = 0;   // explicit: the scheme's default when the text had none
  bool ip_literal = false;  // an IPv4 or IPv6 address, not a name (a browser connects to it as written: no DNS)
  bool operator==(const WebAuthority& other) const noexcept { return host == other.host && port == other.port; }
};

struct WebOrigin {
  std::string scheme;  // "http" or "https"
  WebAuthority authority;
  bool operator==(const WebOrigin& other) const noexcept { return scheme == other.scheme && authority == other.authority; }
  // The serialization a browser sends: "http://robot.local:8000", the default port left out, IPv6 in brackets.
  std::string text() const;
};

// "host", "host:port", "[v6]" or "[v6]:port" (a Host header); `default_port` when no port is written.
std::optional<WebAuthority> parse_web_authority(std::string_view text, std::uint16_t default_port);

// "http://host[:port]" or "https://host[:port]" (an Origin header, or a runtime.listen.allowed_origins entry; a
// trailing "/" is tolerated there). nullopt for anything else, "null" included.
std::optional<WebOrigin> parse_web_origin(std::string_view text);

}  // namespace rcand
