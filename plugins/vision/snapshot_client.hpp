// The HTTP side of a snapshot camera (snapshot_source.cpp): GET of one URL that answers one JPEG per request (what
// many IP cameras and ESP32-CAMs serve at /snapshot.jpg or /capture), on one kept-alive connection, with Boost.Beast.
// Every step is bounded: resolve and connect by `connect_timeout`, the whole exchange by `timeout`; an answer larger
// than `max_bytes` is refused. Each failure is a SourceError naming the URL (without credentials) and what went wrong:
// "snapshot http://cam/snapshot.jpg: 404 Not Found", "...: cannot connect to cam:80: Connection refused".
// Plain HTTP only: an https URL is refused by name when the settings are read (vision.cpp).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace rcand::plugins::vision {

struct SnapshotUrl {
  std::string host;  // name or address, without brackets
  std::uint16_t port = 80;
  std::string target;    // path and query, "/" at least
  std::string userinfo;  // "user:password" for HTTP basic auth, or empty
};
// The URL's parts, or nullopt with `error` saying why (http:// only; no fragment).
std::optional<SnapshotUrl> parse_snapshot_url(std::string_view url, std::string& error);

struct SnapshotLimits {
  std::chrono::milliseconds connect_timeout{3000}, timeout{3000};
  std::size_t max_bytes = 8u << 20;
};

class SnapshotClient {
 public:
  // Throws SourceError when `url` cannot be used (parse_snapshot_url). Connects on the first fetch().
  SnapshotClient(const std::string& url, SnapshotLimits limits);
  ~SnapshotClient();
  SnapshotClient(const SnapshotClient&) = delete;
  SnapshotClient& operator=(const SnapshotClient&) = delete;

  // The body of a 200 answer. Reuses the connection while the camera keeps it alive (one retry on a fresh one when a
  // kept-alive connection turns out closed). Throws SourceError for another status, a failure or a timeout.
  std::shared_ptr<const std::string> fetch();
  std::uint64_t connections() const noexcept;  // opened so far (keep-alive: stays at 1 while the camera allows it)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rcand::plugins::vision
