#include "services/r2r/transports/udp_transport.hpp"

#include <spdlog/spdlog.h>
#include <boost/asio/ip/udp.hpp>

#include <atomic>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <stdexcept>

#include "libs/base/worker_thread.hpp"
#include "services/r2r/transports/message_peek.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;

namespace net = boost::asio;
using udp = net::ip::udp;

UdpDestination parse_udp_destination(const std::string& text, const std::string& key) {
  UdpDestination out;
  std::string host = text, port;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string::npos) throw std::invalid_argument(key + ": '" + text + "' has no closing ']'");
    host = text.substr(1, close - 1);
    if (close + 1 < text.size()) {
      if (text[close + 1] != ':') throw std::invalid_argument(key + ": expected ':port' after ']' in '" + text + "'");
      port = text.substr(close + 2);
    }
  } else if (const auto colon = text.rfind(':'); colon != std::string::npos && text.find(':') == colon) {
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  boost::system::error_code ec;
  net::ip::make_address(host, ec);
  if (ec) throw std::invalid_argument(key + ": '" + host + "' is not an IP address");
  out.host = host;
  if (!text.empty() && (text.back() == ':' || (!port.empty() && port.find_first_not_of("0123456789") != std::string::npos)))
    throw std::invalid_argument(key + ": '" + text + "' has a bad port");
  if (!port.empty()) {
    const long value = std::stol(port.substr(0, 6));
    if (value < 1 || value > 65535) throw std::invalid_argument(key + ": port must be 1..65535 in '" + text + "'");
    out.port = static_cast<std::uint16_t>(value);
  }
  return out;
}

struct UdpTransport::State {
  explicit State(UdpOptions options_in)
      : options(std::move(options_in)), log(options.log ? options.log : spdlog::default_logger()) {}

  const UdpOptions options;
  const std::shared_ptr<spdlog::logger> log;
  // The thread "r2r.udp", from start() on; declared before the socket, which must close before its io_context goes.
  std::unique_ptr<WorkerThread> loop;
  std::optional<udp::socket> socket;  // set before `running`, never reset while the State lives
  std::vector<udp::endpoint> destinations;
  std::atomic<bool> running{false};
  std::atomic<std::uint16_t> port{0};
  std::string buffer = std::string(64 * 1024 + 1, '\0');  // one more than the largest message: detects oversize
  udp::endpoint sender;

  std::shared_mutex deliver_mutex;
  Deliver deliver;
  std::mutex send_mutex;  // senders on any thread, and the close in stop()

  mutable std::mutex counters_mutex;
  UdpCounters counters;

  void receive() {
    socket->async_receive_from(net::buffer(buffer), sender, [this](boost::system::error_code ec, std::size_t bytes) {
      if (ec == net::error::operation_aborted || !running) return;
      if (!ec) {
        {
          std::lock_guard lock(counters_mutex);
          ++counters.received;
        }
        InboundMessage message;
        message.bytes.assign(buffer.data(), bytes);  // an oversize datagram stays oversize: the node refuses it (100)
        message.transport = "udp";
        message.broadcast = true;  // UDP carries status broadcasts only
        const auto address = sender.address();
        message.peer =
            (address.is_v6() ? "[" + address.to_string() + "]" : address.to_string()) + ":" + std::to_string(sender.port());
        std::shared_lock lock(deliver_mutex);
        if (deliver) deliver(std::move(message));
      } else {
        log->debug("r2r udp: receive failed: {}", ec.message());
      }
      receive();
    });
  }
};

UdpTransport::UdpTransport(UdpOptions options) : state_(std::make_shared<State>(std::move(options))) {}

UdpTransport::~UdpTransport() { stop(); }

void UdpTransport::start(Deliver deliver) {
  State& s = *state_;
  if (s.running) return;
  boost::system::error_code ec;
  const auto address = net::ip::make_address(s.options.bind_address, ec);
  if (ec) throw std::runtime_error("runtime.r2r.udp_bind: '" + s.options.bind_address + "' is not an IP address");
  const udp::endpoint local{address, s.options.port};
  if (!s.loop) s.loop = std::make_unique<WorkerThread>("r2r.udp", nullptr);
  if (!s.socket) s.socket.emplace(s.loop->context());
  s.socket->open(local.protocol(), ec);
  if (!ec) s.socket->set_option(udp::socket::reuse_address(true), ec);
  if (!ec) s.socket->set_option(net::socket_base::broadcast(true), ec);
  if (!ec) s.socket->bind(local, ec);
  if (ec)
    throw std::runtime_error("runtime.r2r.udp_port: cannot bind UDP " + s.options.bind_address + ":" +
                             std::to_string(s.options.port) + ": " + ec.message());
  s.port = s.socket->local_endpoint().port();
  for (const auto& destination : s.options.destinations)
    s.destinations.emplace_back(net::ip::make_address(destination.host), destination.port ? destination.port : s.port.load());
  {
    std::unique_lock lock(s.deliver_mutex);
    s.deliver = std::move(deliver);
  }
  s.running = true;
  s.receive();  // the loop thread runs the receive from here on
  s.log->info("r2r udp: status on port {} to {} destination(s)", s.port.load(), s.destinations.size());
}

bool UdpTransport::send(const std::string& bytes, const std::optional<std::string>& target_id) {
  State& s = *state_;
  if (!s.running || target_id || s.destinations.empty()) return false;
  if (bytes.size() > s.options.max_datagram_bytes) return false;
  if (peek_message(bytes).type != "status") return false;
  // Synchronous sends of one datagram are non-blocking in practice (UDP) and thread-safe on distinct calls.
  bool any = false;
  std::lock_guard send_lock(s.send_mutex);
  if (!s.socket->is_open()) return false;
  for (const auto& destination : s.destinations) {
    boost::system::error_code ec;
    s.socket->send_to(net::buffer(bytes), destination, 0, ec);
    std::lock_guard lock(s.counters_mutex);
    if (ec) {
      ++s.counters.send_failed;
    } else {
      ++s.counters.sent;
      any = true;
    }
  }
  return any;
}

void UdpTransport::stop() noexcept {
  State& s = *state_;
  {
    std::unique_lock lock(s.deliver_mutex);
    s.deliver = nullptr;
  }
  if (!s.running.exchange(false)) return;
  try {
    s.loop->post([&s] {
      boost::system::error_code ec;
      std::lock_guard lock(s.send_mutex);
      s.socket->close(ec);
    });
  } catch (...) {  // no memory to post the close: the socket closes with the State
  }
  s.loop->stop_after_queued();
}

std::uint16_t UdpTransport::bound_port() const noexcept { return state_->port; }

UdpCounters UdpTransport::counters() const {
  std::lock_guard lock(state_->counters_mutex);
  return state_->counters;
}

}  // namespace rcand::services::r2r
