// The browser-origin rule (libs/http/origin_policy.hpp, docs/protocol.md §3.9) and the parsing under it
// (libs/rcan/web_origin.hpp): requests without Origin or Sec-Fetch-Site are never touched; a browser page is allowed
// when it is the robot's own (same scheme and host:port as the Host it sent, and over plain HTTP a name the robot
// knows) or listed; everything else, `null` and DNS rebinding included, is refused.
#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>

#include "libs/http/origin_policy.hpp"
#include "libs/rcan/web_origin.hpp"

using rcand::parse_web_authority;
using rcand::parse_web_origin;
using rcand::http::OriginPolicy;
using rcand::http::Request;

namespace {

Request browser_request(std::string host, std::string origin, bool secure = false) {
  Request request;
  request.method = "POST";
  request.path = "/api/estop/clear";
  request.headers["host"] = std::move(host);
  if (!origin.empty()) request.headers["origin"] = std::move(origin);
  request.headers["sec-fetch-site"] = "cross-site";
  request.secure = secure;
  return request;
}

const OriginPolicy kPolicy({{"https://fleet.example.com", "http://rover-3.lan:8000"}, {"alex", "alex.local", "sim-rover.local"}});

bool allowed(const Request& request) { return !kPolicy.check(request).has_value(); }

}  // namespace

TEST_CASE("web origins and Host authorities parse as browsers send them, and nothing else does") {
  const auto origin = parse_web_origin("http://Robot.Local:8000");
  REQUIRE(origin);
  CHECK(origin->scheme == "http");
  CHECK(origin->authority.host == "robot.local");
  CHECK(origin->authority.port == 8000);
  CHECK_FALSE(origin->authority.ip_literal);
  CHECK(origin->text() == "http://robot.local:8000");
  CHECK(parse_web_origin("https://fleet.example.com")->authority.port == 443);
  CHECK(parse_web_origin("https://fleet.example.com:443")->text() == "https://fleet.example.com");
  CHECK(parse_web_origin("http://[::1]:8000")->authority.host == "::1");
  CHECK(parse_web_origin("http://[::1]:8000")->text() == "http://[::1]:8000");
  CHECK(parse_web_origin("http://127.0.0.1:8000")->authority.ip_literal);
  CHECK(parse_web_origin("http://fleet.example.com/")->text() == "http://fleet.example.com");  // config entries
  for (const char* bad : {"null", "", "*", "file://", "chrome-extension://abc", "http://", "http://a b", "http://x/path",
                          "http://user@x", "http://x:0", "http://x:65536", "http://x:80:80", "http://x?q", "ws://x",
                          "http://[::1", "http://::1:80", "http://.x", "http://x,http://y"})
    CHECK_FALSE_MESSAGE(parse_web_origin(bad), bad);

  CHECK(parse_web_authority("LOCALHOST.:8000", 80)->host == "localhost");
  CHECK(parse_web_authority("robot.local", 80)->port == 80);
  CHECK(parse_web_authority("[::1]", 443)->port == 443);
  CHECK(parse_web_authority("[::1]:9", 80)->ip_literal);
  CHECK_FALSE(parse_web_authority("a, b", 80));  // two Host headers, joined
  CHECK_FALSE(parse_web_authority("[fe80::1%eth0]:80", 80));
}

TEST_CASE("origin rule: requests without Origin or Sec-Fetch-Site (curl, rcanctl, robots) are not refused by origin") {
  Request curl;
  curl.method = "POST";
  curl.headers["host"] = "evil.example:8000";  // whatever it says
  CHECK(allowed(curl));
  // In auth mode open their Host must name the robot: a rebinding page's same-origin GET looks just like this.
  CHECK(kPolicy.check(curl, true));
  curl.headers["host"] = "localhost:8000";
  CHECK_FALSE(kPolicy.check(curl, true));
  curl.headers["host"] = "127.0.0.1";
  CHECK_FALSE(kPolicy.check(curl, true));
  curl.headers.erase("host");  // HTTP/1.0
  CHECK(allowed(curl));
  CHECK_FALSE(kPolicy.check(curl, true));
}

TEST_CASE("origin rule: the robot's own pages, as reached by IP, localhost or its names, are allowed") {
  CHECK(allowed(browser_request("127.0.0.1:8000", "http://127.0.0.1:8000")));
  CHECK(allowed(browser_request("localhost:8000", "http://localhost:8000")));
  CHECK(allowed(browser_request("app.localhost:8000", "http://app.localhost:8000")));
  CHECK(allowed(browser_request("[::1]:8000", "http://[::1]:8000")));
  CHECK(allowed(browser_request("192.168.1.20:8000", "http://192.168.1.20:8000")));
  CHECK(allowed(browser_request("alex.local:8000", "http://alex.local:8000")));
  CHECK(allowed(browser_request("ALEX.local.:8000", "http://alex.local:8000")));
  CHECK(allowed(browser_request("sim-rover.local:8000", "http://sim-rover.local:8000")));
  CHECK(allowed(browser_request("localhost", "http://localhost")));  // port 80 on both sides, written or not
  CHECK(allowed(browser_request("localhost:80", "http://localhost")));
  CHECK(allowed(browser_request("localhost:9000", "http://localhost:9000")));  // an ssh -L port: still the robot's page
  // A same-origin GET or a navigation carries no Origin: its Host alone is checked.
  CHECK(allowed(browser_request("127.0.0.1:8000", "")));
}

TEST_CASE("origin rule: another origin, null, or a page on another port is refused; a listed one is allowed") {
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "http://127.0.0.1:8001")));  // another loopback port
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "http://localhost:8000")));  // same machine, another origin
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "https://127.0.0.1:8000")));
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "null")));
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "http://127.0.0.1:8000, http://127.0.0.1:8000")));
  CHECK_FALSE(allowed(browser_request("", "http://127.0.0.1:8000")));  // no Host to compare with
  const auto refusal = kPolicy.check(browser_request("127.0.0.1:8000", "http://127.0.0.1:8001"));
  REQUIRE(refusal);
  CHECK(refusal->origin == "http://127.0.0.1:8001");
  CHECK(refusal->message.find("runtime.listen.allowed_origins") != std::string::npos);

  CHECK(allowed(browser_request("127.0.0.1:8000", "https://fleet.example.com")));
  CHECK(allowed(browser_request("192.168.1.20:8000", "https://FLEET.example.com:443")));
  CHECK_FALSE(allowed(browser_request("127.0.0.1:8000", "http://fleet.example.com")));  // listed with https only
}

TEST_CASE("origin rule: DNS rebinding (a foreign name resolving to the robot) is refused, with or without Origin") {
  // evil.example:8000 now resolves to 127.0.0.1: its page is same-origin with the robot by host:port.
  const auto refusal = kPolicy.check(browser_request("evil.example:8000", "http://evil.example:8000"));
  REQUIRE(refusal);
  CHECK(refusal->message.find("'evil.example' is not a name of this robot") != std::string::npos);
  CHECK_FALSE(allowed(browser_request("evil.example:8000", "")));  // its same-origin GETs (no Origin) too
  CHECK_FALSE(allowed(browser_request("127.0.0.1.nip.io:8000", "http://127.0.0.1.nip.io:8000")));
  // A name the operator listed is the robot's.
  CHECK(allowed(browser_request("rover-3.lan:8000", "http://rover-3.lan:8000")));
  CHECK(allowed(browser_request("rover-3.lan:8000", "")));
  // Over TLS the certificate proves the name: the robot's own https page is allowed whatever its name.
  CHECK(allowed(browser_request("rover.example.com:8443", "https://rover.example.com:8443", true)));
  CHECK_FALSE(allowed(browser_request("rover.example.com:8443", "http://rover.example.com:8443", true)));
}

TEST_CASE("origin rule: the machine's own names come from its host name and metadata.robot_name") {
  const auto names = OriginPolicy::own_host_names("Sim-Rover");
  CHECK(std::find(names.begin(), names.end(), "sim-rover.local") != names.end());
  CHECK(names.size() >= 2);                                      // the host name and its .local name
  const auto spaced = OriginPolicy::own_host_names("My Robot");  // not a DNS label: no .local name from it
  CHECK(std::find(spaced.begin(), spaced.end(), "my robot.local") == spaced.end());
  CHECK_THROWS_AS(OriginPolicy({{"null"}, {}}), std::invalid_argument);
}
