#include "libs/rcan/web_origin.hpp"

#include <boost/asio/ip/address.hpp>

#include <algorithm>
#include <charconv>

namespace rcand {
namespace {

// A DNS name as browsers send it (letters, digits, '-', '_', '.'); anything else (spaces, '@', '%', ...) is refused.
bool is_host_name(std::string_view name) {
  if (name.empty() || name.size() > 253 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_' || c == '.'; });
}

std::optional<std::uint16_t> parse_port(std::string_view digits) {
  unsigned value = 0;
  if (digits.empty() || digits.size() > 5) return std::nullopt;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec != std::errc() || end != digits.data() + digits.size() || value == 0 || value > 65535) return std::nullopt;
  return static_cast<std::uint16_t>(value);
}

std::string lower(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

}  // namespace

std::string WebOrigin::text() const {
  const bool v6 = authority.ip_literal && authority.host.find(':') != std::string::npos;
  std::string out = scheme + "://" + (v6 ? "[" + authority.host + "]" : authority.host);
  const std::uint16_t default_port = scheme == "https" ? 443 : 80;
  if (authority.port != default_port) out += ":" + std::to_string(authority.port);
  return out;
}

std::optional<WebAuthority> parse_web_authority(std::string_view text, std::uint16_t default_port) {
  WebAuthority authority;
  std::string_view host = text;
  if (text.starts_with('[')) {
    const auto close = text.find(']');
    if (close == std::string_view::npos) return std::nullopt;
    const auto rest = text.substr(close + 1);
    if (rest.empty()) authority.port = default_port;
    else if (const auto parsed = rest.starts_with(':') ? parse_port(rest.substr(1)) : std::nullopt) authority.port = *parsed;
    else return std::nullopt;
    boost::system::error_code ec;
    const auto address = boost::asio::ip::make_address_v6(std::string(text.substr(1, close - 1)), ec);
    if (ec || address.scope_id() != 0) return std::nullopt;
    authority.host = address.to_string();
    authority.ip_literal = true;
    return authority;
  }
  if (const auto colon = text.rfind(':'); colon != std::string_view::npos) {
    host = text.substr(0, colon);
    const auto parsed = parse_port(text.substr(colon + 1));
    if (!parsed) return std::nullopt;
    authority.port = *parsed;
  } else {
    authority.port = default_port;
  }
  authority.host = lower(host);
  if (authority.host.ends_with('.')) authority.host.pop_back();  // "robot.local." is "robot.local"
  if (!is_host_name(authority.host)) return std::nullopt;
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address_v4(authority.host, ec);
  authority.ip_literal = !ec;
  if (authority.ip_literal) authority.host = address.to_string();
  return authority;
}

std::optional<WebOrigin> parse_web_origin(std::string_view text) {
  WebOrigin origin;
  const auto separator = text.find("://");
  if (separator == std::string_view::npos) return std::nullopt;
  origin.scheme = lower(text.substr(0, separator));
  if (origin.scheme != "http" && origin.scheme != "https") return std::nullopt;
  auto rest = text.substr(separator + 3);
  if (rest.ends_with('/')) rest.remove_suffix(1);
  if (rest.find_first_of("/?#@") != std::string_view::npos) return std::nullopt;
  auto authority = parse_web_authority(rest, origin.scheme == "https" ? 443 : 80);
  if (!authority) return std::nullopt;
  origin.authority = std::move(*authority);
  return origin;
}

}  // namespace rcand
