#include "watch_command.hpp"

#include <unistd.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <atomic>
#include <csignal>
#include <iostream>
#include <optional>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "human_format.hpp"
#include "libs/http/connection_stream.hpp"
#include "libs/http/tls_context.hpp"
#include "robot_connection.hpp"
#include "text_table.hpp"

namespace rcand::rcanctl {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using nlohmann::json;

std::atomic<bool> watch_interrupted{false};
extern "C" void on_watch_interrupt(int) { watch_interrupted.store(true); }

std::string watch_cell(const json& value) { return human_text(value); }

std::string states(const json& map) {
  std::string text;
  if (map.is_object())
    for (const auto& [name, state] : map.items()) text += (text.empty() ? "" : " ") + name + "=" + watch_cell(state);
  return text.empty() ? "-" : text;
}

std::string pose_text(const json& pose) {
  if (!pose.is_object()) return "-";
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "x %.2f m  y %.2f m  heading %.1f deg", pose.value("x_m", 0.0), pose.value("y_m", 0.0),
                pose.value("heading_deg", 0.0));
  return buffer;
}

// By value: operator[] on a copy yields null for a missing field (on a const json it would be undefined).
void print_table(json frame, std::ostream& out) {
  out << "\x1b[H\x1b[2J";  // home and clear: the table is redrawn in place
  print_text_table({{"field", "value"},
                    {"estopped", frame["estopped"] == true ? "YES" : "no"},
                    {"state", watch_cell(frame["state"])},
                    {"nav_running", watch_cell(frame["nav_running"])},
                    {"pose", pose_text(frame["pose"])},
                    {"obstacles", watch_cell(frame["obstacles"])},
                    {"battery_v", watch_cell(frame["battery_v"])},
                    {"capabilities", states(frame["capabilities"])},
                    {"drivers", states(frame["drivers"])},
                    {"uptime_s", watch_cell(frame["uptime_s"])},
                    {"seq / event", watch_cell(frame["seq"]) + " / " + watch_cell(frame["event"])}},
                   out);
  if (frame["estop"].is_object())
    out << "\ne-stop since " << human_time(frame["estop"]["since_ms"]) << ": " << watch_cell(frame["estop"]["reason"]) << " (by "
        << watch_cell(frame["estop"]["source"]) << ")\n";
  out << "\nCtrl-C to quit" << std::flush;
}

void print_line(json frame, std::ostream& out) {
  out << "seq " << watch_cell(frame["seq"]) << "  " << watch_cell(frame["event"]) << "  estopped "
      << watch_cell(frame["estopped"]) << "  state " << watch_cell(frame["state"]) << "  nav " << watch_cell(frame["nav_running"])
      << "  pose " << pose_text(frame["pose"]) << std::endl;
}

// Runs the io_context until `done` or `limit`; false when the limit passed first (or Ctrl-C).
bool run_until(net::io_context& io, const bool& done, std::chrono::milliseconds limit) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (!done && !watch_interrupted.load() && std::chrono::steady_clock::now() < until) {
    io.run_for(std::chrono::milliseconds(100));
    if (io.stopped()) io.restart();
  }
  return done;
}

}  // namespace

int run_watch(std::span<const std::string> args) {
  RobotOptions options;
  std::optional<int> frames_wanted;
  const auto app = make_command_app(
      "rcanctl watch",
      "Live telemetry from WS /ws/telemetry (a frame every 200 ms, and at once on an e-stop): a table redrawn in\n"
      "place, one line per frame when the output is not a terminal, or each frame as one JSON line with --json.",
      "--timeout: connecting, and the longest gap between frames before the connection counts as lost.\n"
      "The token may be any role's: telemetry needs the status scope. TLS (wss) with https:// hosts or --cacert.\n"
      "Exit: 0 after --frames N or Ctrl-C, 1 refused (401/403), unreachable or connection lost, 2 usage.");
  app->add_option_function<int>(
         "--frames", [&frames_wanted](const int& count) { frames_wanted = count; }, "stop after N frames (default: Ctrl-C)")
      ->check(CLI::Range(1, 1000000000));
  add_robot_options(*app, options);
  if (auto done = parse_robot_command(*app, args, options)) return *done;
  const std::string where = options.host + ":" + std::to_string(options.port);
  net::io_context io;
  // wss when TLS is asked for: the robot's certificate verified before the upgrade (and its token) is sent.
  const auto tls = client_tls(options.tls, options.host);
  auto context = tls ? http::make_client_tls_context(*tls) : nullptr;
  websocket::stream<http::ConnectionStream> ws(context ? http::ConnectionStream(http::TcpStream(io), context)
                                                       : http::ConnectionStream(io));
  bool done = false;
  beast::error_code result;
  net::ip::tcp::resolver resolver(io);
  resolver.async_resolve(options.host, std::to_string(options.port),
                         [&](beast::error_code ec, net::ip::tcp::resolver::results_type found) {
                           if (ec) {
                             result = ec;
                             done = true;
                             return;
                           }
                           beast::get_lowest_layer(ws).async_connect(found, [&](beast::error_code connect_ec, const auto&) {
                             result = connect_ec;
                             done = true;
                           });
                         });
  if (!run_until(io, done, options.timeout) || result) {
    std::cerr << "rcanctl watch: cannot connect to " << where << ": " << (result ? result.message() : "timed out") << "\n";
    return kExitFailure;
  }
  if (auto* layer = ws.next_layer().tls()) {
    http::expect_server_name(layer->native_handle(), options.host);
    done = false;
    layer->async_handshake(net::ssl::stream_base::client, [&](beast::error_code ec) {
      result = ec;
      done = true;
    });
    if (!run_until(io, done, options.timeout) || result) {
      std::cerr << "rcanctl watch: TLS handshake with " << where
                << " failed: " << (result ? http::tls_failure(layer->native_handle(), result) : "timed out") << "\n";
      return kExitFailure;
    }
  }
  ws.set_option(websocket::stream_base::decorator([token = options.token](websocket::request_type& request) {
    request.set(beast::http::field::authorization, "Bearer " + token);
    request.set(beast::http::field::user_agent, "rcanctl");
  }));
  websocket::response_type response;
  done = false;
  ws.async_handshake(response, where, "/ws/telemetry", [&](beast::error_code ec) {
    result = ec;
    done = true;
  });
  if (!run_until(io, done, options.timeout) || result) {
    const int status = static_cast<int>(response.result_int());
    const json body = json::parse(response.body(), nullptr, false);
    const std::string why = body.is_object() && body.contains("error") && body["error"].is_string()
                                ? body["error"].get<std::string>()
                                : (result ? result.message() : "timed out");
    if (status == 401 || status == 403)
      std::cerr << "rcanctl watch: authentication failed (HTTP " << status << "): " << why << "\n";
    else if (status != 0)
      std::cerr << "rcanctl watch: " << where << " refused /ws/telemetry (HTTP " << status << "): " << why << "\n";
    else std::cerr << "rcanctl watch: upgrade to /ws/telemetry on " << where << " failed: " << why << "\n";
    return kExitFailure;
  }

  std::signal(SIGINT, on_watch_interrupt);
  const bool table = !options.json && ::isatty(STDOUT_FILENO) == 1;
  beast::flat_buffer buffer;
  int shown = 0;
  while (!frames_wanted || shown < *frames_wanted) {
    done = false;
    ws.async_read(buffer, [&](beast::error_code ec, std::size_t) {
      result = ec;
      done = true;
    });
    if (!run_until(io, done, options.timeout) || result) {
      if (watch_interrupted.load()) break;
      std::cerr << (table ? "\n" : "") << "rcanctl watch: connection to " << where
                << " lost: " << (result ? result.message() : "no frame for " + std::to_string(options.timeout.count()) + " ms")
                << "\n";
      return kExitFailure;
    }
    const std::string text = beast::buffers_to_string(buffer.data());
    buffer.consume(buffer.size());
    const json message = json::parse(text, nullptr, false);
    if (!message.is_object() || message.value("type", "") != "telemetry") continue;
    ++shown;
    if (options.json) std::cout << message.dump() << std::endl;
    else if (table) print_table(message, std::cout);
    else print_line(message, std::cout);
  }
  if (table) std::cout << "\n";
  beast::error_code ignored;
  beast::get_lowest_layer(ws).socket().close(ignored);  // no close handshake to wait for: we are leaving
  return kExitOk;
}

}  // namespace rcand::rcanctl
