#include "libs/http/origin_policy.hpp"

#include <unistd.h>

#include <algorithm>
#include <climits>
#include <stdexcept>

namespace rcand::http {
namespace {

constexpr std::size_t kQuotedOrigin = 200;  // an Origin quoted back is cut here

std::string quoted(std::string_view text) {
  std::string out(text.substr(0, kQuotedOrigin));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  return out;
}

bool is_dns_label(std::string_view name) {
  return !name.empty() && name.size() <= 63 && name.front() != '-' && name.back() != '-' &&
         std::all_of(name.begin(), name.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-'; });
}

std::string lower(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

}  // namespace

OriginPolicy::OriginPolicy(OriginPolicySettings settings) {
  for (const auto& text : settings.allowed_origins) {
    auto origin = parse_web_origin(text);
    if (!origin) throw std::invalid_argument("runtime.listen.allowed_origins: '" + quoted(text) + "' is not an origin");
    names_.push_back(origin->authority.host);
    allowed_.push_back(std::move(*origin));
  }
  for (const auto& name : settings.own_names) names_.push_back(lower(name));
}

std::vector<std::string> OriginPolicy::own_host_names(std::string_view robot_name) {
  std::vector<std::string> names;
  char host[HOST_NAME_MAX + 1] = {};
  if (::gethostname(host, sizeof host - 1) == 0 && host[0] != '\0') {
    const std::string name = lower(host);
    names.push_back(name);
    if (!name.ends_with(".local")) names.push_back(name.substr(0, name.find('.')) + ".local");
  }
  if (const std::string robot = lower(robot_name); is_dns_label(robot)) names.push_back(robot + ".local");
  return names;
}

bool OriginPolicy::known_name(const WebAuthority& host) const {
  if (host.ip_literal || host.host == "localhost" || host.host.ends_with(".localhost")) return true;
  return std::find(names_.begin(), names_.end(), host.host) != names_.end();
}

bool OriginPolicy::listed(const WebOrigin& origin) const {
  return std::find(allowed_.begin(), allowed_.end(), origin) != allowed_.end();
}

std::optional<OriginPolicy::Refusal> OriginPolicy::check(const Request& request, bool every_host) const {
  const auto origin_header = request.header("origin");
  const bool browser = origin_header || request.header("sec-fetch-site");
  if (!browser && (!every_host || !request.header("host"))) return std::nullopt;  // curl, rcanctl, robots
  const std::string scheme = request.secure ? "https" : "http";
  std::optional<WebAuthority> host;
  if (const auto host_header = request.header("host")) host = parse_web_authority(*host_header, request.secure ? 443 : 80);
  if (origin_header) {
    const auto origin = parse_web_origin(*origin_header);
    if (origin && listed(*origin)) return std::nullopt;
    const std::string shown = quoted(*origin_header);
    if (!origin)
      return Refusal{
          "a page of origin '" + shown + "' may not use this robot: only its own pages and runtime.listen.allowed_origins may",
          shown};
    if (!host || origin->scheme != scheme || !(origin->authority == *host))
      return Refusal{"a page of " + origin->text() +
                         " (another origin than this robot's) may not use this robot; list it in "
                         "runtime.listen.allowed_origins to allow it",
                     shown};
  }
  // The page is the robot's own by its Host header (or sent no Origin); over plain HTTP the name must be the robot's.
  if (request.secure || (host && known_name(*host))) return std::nullopt;
  if (!host) return Refusal{"a request without a valid Host header", origin_header ? quoted(*origin_header) : ""};
  return Refusal{"'" + host->host + "' is not a name of this robot (a DNS rebinding page?); use its IP address, localhost or " +
                     "its .local name, or list " + WebOrigin{scheme, *host}.text() + " in runtime.listen.allowed_origins",
                 origin_header ? quoted(*origin_header) : std::string()};
}

}  // namespace rcand::http
