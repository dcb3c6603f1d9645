#include "r2r_command.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <spdlog/logger.h>

#include <csignal>
#include <functional>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <unistd.h>
#include <thread>

#include "exit_codes.hpp"
#include "libs/http/client.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"

namespace rcand::rcanctl {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using nlohmann::json;

constexpr std::string_view kR2rUsage =
    "usage: rcanctl r2r send --type TYPE [--target NAME] [--payload JSON] [--as NAME] [--wait MS] [robot options]\n"
    "       rcanctl r2r watch [--timeout S] [robot options] | rcanctl r2r watch --mqtt HOST[:PORT] [--timeout S]\n"
    "       rcanctl r2r auction [--task-id ID] [--description TEXT] [--require CAP,...] [--at X,Y] [robot options]\n"
    "  robot options: [--host HOST] [--port PORT] (--token T | --token-file FILE | $RCAND_TOKEN) [--json]\n"
    "  send: connects to WS /ws/r2r as peer NAME (default rcanctl), sends one message, prints what comes back within\n"
    "        --wait MS (default 2000). watch: prints R2R traffic until Ctrl-C or --timeout (WS: what the robot sends\n"
    "        its peers; --mqtt: every message on r2r/#). auction: the robot runs an auction and the bids and the\n"
    "        winner are printed. Exit: 0 success, 1 refused/failed/no winner, 2 usage error.\n";

volatile std::sig_atomic_t interrupted = 0;

struct Options {
  std::string sub;
  std::string host = "127.0.0.1";
  std::uint16_t port = 8000;
  std::string token;
  bool as_json = false;
  std::string type, target, as = "rcanctl";
  json payload = json::object();
  std::chrono::milliseconds wait{2000};
  std::optional<std::chrono::milliseconds> timeout;
  std::optional<std::string> mqtt;
  json task = json::object();
};

std::optional<long> number(const std::string& text) {
  try {
    std::size_t used = 0;
    const long value = std::stol(text, &used);
    if (used != text.size()) return std::nullopt;
    return value;
  } catch (...) {
    return std::nullopt;
  }
}

// Returns the exit code when parsing ends the command (usage error, --help).
std::optional<int> parse(std::span<const std::string> args, Options& o, std::ostream& out, std::ostream& err) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    (args.empty() ? err : out) << kR2rUsage;
    return args.empty() ? kExitUsage : kExitOk;
  }
  o.sub = args[0];
  if (o.sub != "send" && o.sub != "watch" && o.sub != "auction") {
    err << "rcanctl r2r: unknown subcommand '" << o.sub << "'\n" << kR2rUsage;
    return kExitUsage;
  }
  std::string token_file;
  auto fail = [&](const std::string& message) {
    err << "rcanctl r2r " << o.sub << ": " << message << "\n";
    return kExitUsage;
  };
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--json") {
      o.as_json = true;
      continue;
    }
    if (arg == "--help") {
      out << kR2rUsage;
      return kExitOk;
    }
    if (i + 1 >= args.size()) return fail(arg + " needs a value");
    const std::string& value = args[++i];
    if (arg == "--host") o.host = value;
    else if (arg == "--port") {
      const auto port = number(value);
      if (!port || *port < 1 || *port > 65535) return fail("--port must be 1..65535");
      o.port = static_cast<std::uint16_t>(*port);
    } else if (arg == "--token") o.token = value;
    else if (arg == "--token-file") token_file = value;
    else if (arg == "--type" && o.sub == "send") o.type = value;
    else if (arg == "--target" && o.sub == "send") o.target = value;
    else if (arg == "--as" && o.sub == "send") o.as = value;
    else if (arg == "--payload" && o.sub == "send") {
      o.payload = json::parse(value, nullptr, false);
      if (!o.payload.is_object()) return fail("--payload must be a JSON object");
    } else if (arg == "--wait" && o.sub == "send") {
      const auto ms = number(value);
      if (!ms || *ms < 0) return fail("--wait must be milliseconds >= 0");
      o.wait = std::chrono::milliseconds(*ms);
    } else if (arg == "--timeout" && o.sub == "watch") {
      const auto s = number(value);
      if (!s || *s < 1) return fail("--timeout must be whole seconds >= 1");
      o.timeout = std::chrono::seconds(*s);
    } else if (arg == "--mqtt" && o.sub == "watch") o.mqtt = value;
    else if (arg == "--task-id" && o.sub == "auction") o.task["task_id"] = value;
    else if (arg == "--description" && o.sub == "auction") o.task["description"] = value;
    else if (arg == "--require" && o.sub == "auction") {
      json caps = json::array();
      std::size_t start = 0;
      while (start <= value.size()) {
        const auto comma = value.find(',', start);
        const std::string cap = value.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
        if (!cap.empty()) caps.push_back(cap);
        if (comma == std::string::npos) break;
        start = comma + 1;
      }
      o.task["required_capabilities"] = caps;
    } else if (arg == "--at" && o.sub == "auction") {
      const auto comma = value.find(',');
      try {
        if (comma == std::string::npos) throw std::invalid_argument("x");
        o.task["location"] = {{"x", std::stod(value.substr(0, comma))}, {"y", std::stod(value.substr(comma + 1))}};
      } catch (...) {
        return fail("--at must be X,Y (metres, fleet frame)");
      }
    } else {
      return fail("unknown option " + arg);
    }
  }
  if (o.sub == "send" && o.type.empty()) return fail("--type is required");
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in || !std::getline(in, o.token) || o.token.empty()) return fail("cannot read --token-file " + token_file);
  }
  if (o.token.empty())
    if (const char* env = std::getenv("RCAND_TOKEN")) o.token = env;
  if (o.token.empty() && !o.mqtt) return fail("a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN");
  return std::nullopt;
}

// One WebSocket connection to the robot's /ws/r2r; every wait bounded.
class Link {
 public:
  // Throws std::runtime_error saying why (refused, 401, ...).
  Link(const Options& o) {
    beast::error_code result = net::error::would_block;
    net::ip::tcp::resolver resolver(ioc_);
    const auto endpoints = resolver.resolve(o.host, std::to_string(o.port));
    beast::get_lowest_layer(ws_).async_connect(endpoints, [&](beast::error_code ec, const auto&) { result = ec; });
    run(std::chrono::seconds(5));
    if (result) throw std::runtime_error("cannot connect to " + o.host + ":" + std::to_string(o.port) + ": " + result.message());
    ws_.set_option(websocket::stream_base::decorator([token = o.token](websocket::request_type& request) {
      request.set(beast::http::field::authorization, "Bearer " + token);
      request.set(beast::http::field::user_agent, "rcanctl");
    }));
    websocket::response_type response;
    result = net::error::would_block;
    ws_.async_handshake(response, o.host + ":" + std::to_string(o.port), "/ws/r2r", [&](beast::error_code ec) { result = ec; });
    run(std::chrono::seconds(5));
    if (result) {
      const json body = json::parse(response.body(), nullptr, false);
      const std::string why = body.is_object() && body.contains("error") ? body["error"].get<std::string>() : result.message();
      throw std::runtime_error("the robot refused the R2R connection (HTTP " + std::to_string(response.result_int()) + "): " + why);
    }
  }
  void send(const std::string& text) {
    beast::error_code result = net::error::would_block;
    ws_.text(true);
    ws_.async_write(net::buffer(text), [&](beast::error_code ec, std::size_t) { result = ec; });
    run(std::chrono::seconds(5));
    if (result) throw std::runtime_error("send failed: " + result.message());
  }
  // Calls `on_frame` for every frame until `until` (or the connection ends, or Ctrl-C). False when it ended early.
  bool receive_until(std::chrono::steady_clock::time_point until, const std::function<void(const std::string&)>& on_frame) {
    bool ended = false;
    std::function<void()> next = [&] {
      ws_.async_read(buffer_, [&](beast::error_code ec, std::size_t) {
        if (ec) {
          ended = true;
          return;
        }
        on_frame(beast::buffers_to_string(buffer_.data()));
        buffer_.consume(buffer_.size());
        next();
      });
    };
    next();
    while (!ended && !interrupted && std::chrono::steady_clock::now() < until) ioc_.run_for(std::chrono::milliseconds(100));
    return !ended;
  }

 private:
  void run(std::chrono::milliseconds timeout) {
    ioc_.run_for(timeout);
    ioc_.restart();
  }
  net::io_context ioc_;
  websocket::stream<beast::tcp_stream> ws_{ioc_};
  beast::flat_buffer buffer_;
};

std::string one_line(const json& message) {
  const std::string type = message.value("type", "?");
  const json& header = message.contains("header") && message["header"].is_object() ? message["header"] : json::object();
  std::string text = header.value("source_id", "?") + " -> " + header.value("target_id", "*") + "  " + type;
  json payload = message.contains("payload") ? message["payload"] : json::object();
  return text + "  " + payload.dump();
}

void print_message(const std::string& bytes, bool as_json, std::ostream& out) {
  const json message = json::parse(bytes, nullptr, false);
  if (!message.is_object()) {
    out << (as_json ? json{{"raw", bytes}}.dump() : "(not JSON) " + bytes) << std::endl;
    return;
  }
  json shown = message;
  if (shown.contains("header") && shown["header"].is_object()) shown["header"].erase("auth");  // never print tokens
  out << (as_json ? shown.dump() : one_line(shown)) << std::endl;
}

int run_send(const Options& o, std::ostream& out, std::ostream& err) {
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  json header{{"version", "1.0"}, {"timestamp", now}, {"source_id", o.as}};
  if (!o.target.empty()) header["target_id"] = o.target;
  const json message{{"header", header}, {"type", o.type}, {"payload", o.payload}};
  bool refused = false;
  try {
    Link link(o);
    link.send(message.dump());
    link.receive_until(std::chrono::steady_clock::now() + o.wait, [&](const std::string& frame) {
      const json answer = json::parse(frame, nullptr, false);
      // The robot's periodic status is not an answer to us.
      if (answer.is_object() && answer.value("type", "") == "status" && !answer["header"].contains("target_id")) return;
      if (answer.is_object() && answer.value("type", "") == "error") refused = true;
      print_message(frame, o.as_json, out);
    });
  } catch (const std::exception& e) {
    err << "rcanctl r2r send: " << e.what() << "\n";
    return kExitFailure;
  }
  return refused ? kExitFailure : kExitOk;
}

int run_watch(const Options& o, std::ostream& out, std::ostream& err) {
  std::signal(SIGINT, [](int) { interrupted = 1; });
  const auto until = o.timeout ? std::chrono::steady_clock::now() + *o.timeout : std::chrono::steady_clock::time_point::max();
  if (o.mqtt) {
    kernel::r2r::MqttOptions options;
    const auto colon = o.mqtt->rfind(':');
    options.host = colon == std::string::npos ? *o.mqtt : o.mqtt->substr(0, colon);
    if (colon != std::string::npos) {
      const auto port = number(o.mqtt->substr(colon + 1));
      if (!port || *port < 1 || *port > 65535) {
        err << "rcanctl r2r watch: --mqtt HOST[:PORT] has a bad port\n";
        return kExitUsage;
      }
      options.port = static_cast<std::uint16_t>(*port);
    }
    options.robot_name = "rcanctl-watch";
    options.client_id = "rcanctl-watch-" + std::to_string(::getpid());
    options.extra_subscriptions = {"r2r/#"};
    options.log = std::make_shared<spdlog::logger>("rcanctl");  // no sinks: the watcher prints only traffic
    std::mutex out_mutex;
    kernel::r2r::MqttTransport watcher(options);
    try {
      watcher.start([&](kernel::r2r::InboundMessage message) {
        std::lock_guard lock(out_mutex);
        if (!o.as_json) out << message.peer << "  ";
        print_message(message.bytes, o.as_json, out);
      });
    } catch (const std::exception& e) {
      err << "rcanctl r2r watch: " << e.what() << "\n";
      return kExitFailure;
    }
    while (!interrupted && std::chrono::steady_clock::now() < until) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    watcher.stop();
    return kExitOk;
  }
  try {
    Link link(o);
    if (!link.receive_until(until, [&](const std::string& frame) { print_message(frame, o.as_json, out); })) {
      err << "rcanctl r2r watch: the robot closed the connection\n";
      return kExitFailure;
    }
  } catch (const std::exception& e) {
    err << "rcanctl r2r watch: " << e.what() << "\n";
    return kExitFailure;
  }
  return kExitOk;
}

int run_auction(const Options& o, std::ostream& out, std::ostream& err) {
  http::ClientResponse response;
  try {
    response = http::request(o.host, o.port, "POST", "/api/r2r/auction", o.task.dump(), {{"Authorization", "Bearer " + o.token}},
                             std::chrono::seconds(130));
  } catch (const std::exception& e) {
    err << "rcanctl r2r auction: " << e.what() << "\n";
    return kExitFailure;
  }
  const json result = json::parse(response.body, nullptr, false);
  if (response.status != 200 || !result.is_object()) {
    err << "rcanctl r2r auction: HTTP " << response.status << ": "
        << (result.is_object() && result.contains("error") ? result["error"].get<std::string>() : response.body) << "\n";
    return kExitFailure;
  }
  const bool assigned = result.value("state", "") == "assigned";
  if (o.as_json) {
    out << result.dump() << std::endl;
    return assigned ? kExitOk : kExitFailure;
  }
  out << "task " << result.value("task_id", "?") << ": " << result.value("state", "?") << " after "
      << std::fixed << std::setprecision(0) << result.value("elapsed_ms", 0.0) << " ms, round " << result.value("round", 0) << "\n";
  out << std::left << std::setw(20) << "BIDDER" << std::setw(12) << "COST (s)" << "CAPABILITIES\n";
  for (const auto& bid : result.value("bids", json::array())) {
    std::ostringstream cost;
    cost << std::fixed << std::setprecision(2) << bid.value("cost", 0.0);
    out << std::setw(20) << bid.value("bidder", "?") << std::setw(12) << cost.str()
        << bid.value("capabilities", json::array()).dump() << "\n";
  }
  if (assigned) out << "winner: " << result["winner"].get<std::string>() << " (estimated " << result.value("estimated_time", 0.0) << " s)\n";
  else out << "no winner\n";
  return assigned ? kExitOk : kExitFailure;
}

}  // namespace

int run_r2r(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  Options options;
  if (auto done = parse(args, options, out, err)) return *done;
  if (options.sub == "send") return run_send(options, out, err);
  if (options.sub == "watch") return run_watch(options, out, err);
  return run_auction(options, out, err);
}

int run_r2r(std::span<const std::string> args) { return run_r2r(args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
