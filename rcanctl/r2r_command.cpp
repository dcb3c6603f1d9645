#include "r2r_command.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "libs/http/client.hpp"
#include "mqtt_subscription.hpp"

namespace rcand::rcanctl {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using nlohmann::json;

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
  std::optional<long> count;
  MqttBrokerFlags broker_flags;
  std::optional<MqttBrokerOptions> mqtt;
  json task = json::object();
};

// The robot options of one r2r action (its own copy of the flags: each action lists them in its --help).
void add_r2r_robot_options(CLI::App& action, Options& o, std::string& token_file) {
  action.add_option("--host", o.host, "the robot (default 127.0.0.1)");
  action.add_option("--port", o.port, "its port (default 8000)")->check(CLI::Range(1, 65535));
  action.add_option("--token", o.token, "the bearer token (or --token-file, or $RCAND_TOKEN)");
  action.add_option("--token-file", token_file, "a file holding the token");
  action.add_flag("--json", o.as_json, "JSON lines");
}

// Returns the exit code when parsing ends the command (usage error, --help).
std::optional<int> parse(std::span<const std::string> args, Options& o, std::ostream& out, std::ostream& err) {
  const auto app = make_command_app("rcanctl r2r", "Robot-to-robot (seed 004): one message, the traffic, an auction.",
                                    "Exit: 0 success, 1 refused/failed/no winner, 2 usage error.");
  std::string token_file;
  CLI::App* send =
      app->add_subcommand("send", "connect to WS /ws/r2r as peer --as, send one message, print what comes back within --wait");
  send->add_option("--type", o.type, "the message type")->required();
  send->add_option("--target", o.target, "the peer it is for");
  send->add_option_function<std::string>(
          "--payload", [&o](const std::string& text) { o.payload = json::parse(text, nullptr, false); }, "a JSON object")
      ->check(CLI::Validator(
          [](std::string& text) {
            return json::parse(text, nullptr, false).is_object() ? std::string() : std::string("must be a JSON object");
          },
          "JSON"));
  send->add_option("--as", o.as, "the peer name to connect as (default rcanctl)");
  send->add_option_function<int>(
          "--wait", [&o](const int& ms) { o.wait = std::chrono::milliseconds(ms); }, "milliseconds to wait (default 2000)")
      ->check(CLI::Range(0, 600000));
  CLI::App* watch = app->add_subcommand(
      "watch", "print R2R traffic until Ctrl-C or --timeout (WS: what the robot sends its peers; --mqtt: r2r/#)");
  watch
      ->add_option_function<int>(
          "--timeout", [&o](const int& seconds) { o.timeout = std::chrono::seconds(seconds); }, "stop after S seconds")
      ->check(CLI::Range(1, 86400));
  watch
      ->add_option_function<long>(
          "--count", [&o](const long& n) { o.count = n; }, "exit after N messages")
      ->check(CLI::Range(1L, 1000000000L));
  o.broker_flags.add_to(*watch, "HOST[:PORT]: every message on the broker's r2r/# instead of the robot's WebSocket", false,
                        false);
  CLI::App* auction = app->add_subcommand("auction", "the robot runs an auction; print the bids and the winner");
  auction->add_option_function<std::string>(
      "--task-id", [&o](const std::string& id) { o.task["task_id"] = id; }, "the task's id");
  auction->add_option_function<std::string>(
      "--description", [&o](const std::string& text) { o.task["description"] = text; }, "the task in words");
  auction
      ->add_option_function<std::vector<std::string>>(
          "--require", [&o](const std::vector<std::string>& caps) { o.task["required_capabilities"] = caps; },
          "capabilities a bidder needs, comma-separated")
      ->delimiter(',')
      ->allow_extra_args(false);
  auction
      ->add_option_function<std::vector<double>>(
          "--at",
          [&o](const std::vector<double>& at) {
            o.task["location"] = {{"x", at[0]}, {"y", at[1]}};
          },
          "X,Y: where the task is (metres, fleet frame)")
      ->delimiter(',')
      ->expected(2)
      ->allow_extra_args(false);
  for (CLI::App* action : {send, watch, auction}) add_r2r_robot_options(*action, o, token_file);
  app->require_subcommand(1);
  if (auto done = parse_command_line(*app, args, out, err)) return done;
  o.sub = app->get_subcommands().front()->get_name();
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in || !std::getline(in, o.token) || o.token.empty())
      return usage_error(*app, "cannot read --token-file " + token_file, err);
  }
  if (o.token.empty())
    if (const char* env = std::getenv("RCAND_TOKEN")) o.token = env;
  MqttBrokerOptions broker;
  broker.client_id = "rcanctl-watch-" + std::to_string(::getpid());
  if (auto bad = o.broker_flags.apply(broker)) return usage_error(*app, *bad, err);
  if (o.broker_flags.given()) o.mqtt = std::move(broker);
  if (o.token.empty() && !o.mqtt)
    return usage_error(*app, "a token is required: --token TOKEN, --token-file FILE or $RCAND_TOKEN", err);
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
      throw std::runtime_error("the robot refused the R2R connection (HTTP " + std::to_string(response.result_int()) +
                               "): " + why);
    }
  }
  void send(const std::string& text) {
    beast::error_code result = net::error::would_block;
    ws_.text(true);
    ws_.async_write(net::buffer(text), [&](beast::error_code ec, std::size_t) { result = ec; });
    run(std::chrono::seconds(5));
    if (result) throw std::runtime_error("send failed: " + result.message());
  }
  // Calls on_frame with each message until `until`, Ctrl-C or on_frame returns false; false when the robot hung up.
  bool receive_until(std::chrono::steady_clock::time_point until, const std::function<bool(const std::string&)>& on_frame) {
    bool ended = false, enough = false;
    std::function<void()> next = [&] {
      ws_.async_read(buffer_, [&](beast::error_code ec, std::size_t) {
        if (ec) {
          ended = true;
          return;
        }
        enough = !on_frame(beast::buffers_to_string(buffer_.data()));
        buffer_.consume(buffer_.size());
        if (!enough) next();
      });
    };
    next();
    while (!ended && !enough && !interrupted && std::chrono::steady_clock::now() < until)
      ioc_.run_for(std::chrono::milliseconds(100));
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
      if (answer.is_object() && answer.value("type", "") == "status" && !answer["header"].contains("target_id")) return true;
      if (answer.is_object() && answer.value("type", "") == "error") refused = true;
      print_message(frame, o.as_json, out);
      return true;
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
  long printed = 0;
  auto enough = [&] { return o.count && printed >= *o.count; };
  if (o.mqtt) {
    std::mutex mutex;
    std::condition_variable counted;
    try {
      MqttSubscription watcher(*o.mqtt, "r2r/#", [&](std::string_view topic, std::string_view payload) {
        std::lock_guard lock(mutex);
        if (enough()) return;
        if (!o.as_json) out << topic << "  ";
        print_message(std::string(payload), o.as_json, out);
        ++printed;
        counted.notify_all();
      });
      std::unique_lock lock(mutex);
      while (!interrupted && !enough() && std::chrono::steady_clock::now() < until)
        counted.wait_for(lock, std::chrono::milliseconds(100));  // a short wait: Ctrl-C only sets a flag
    } catch (const std::exception& e) {
      err << "rcanctl r2r watch: " << e.what() << "\n";
      return kExitFailure;
    }
    return kExitOk;
  }
  try {
    Link link(o);
    const bool open = link.receive_until(until, [&](const std::string& frame) {
      print_message(frame, o.as_json, out);
      ++printed;
      return !enough();
    });
    if (!open) {
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
  out << "task " << result.value("task_id", "?") << ": " << result.value("state", "?") << " after " << std::fixed
      << std::setprecision(0) << result.value("elapsed_ms", 0.0) << " ms, round " << result.value("round", 0) << "\n";
  out << std::left << std::setw(20) << "BIDDER" << std::setw(12) << "COST (s)"
      << "CAPABILITIES\n";
  for (const auto& bid : result.value("bids", json::array())) {
    std::ostringstream cost;
    cost << std::fixed << std::setprecision(2) << bid.value("cost", 0.0);
    out << std::setw(20) << bid.value("bidder", "?") << std::setw(12) << cost.str()
        << bid.value("capabilities", json::array()).dump() << "\n";
  }
  if (assigned)
    out << "winner: " << result["winner"].get<std::string>() << " (estimated " << result.value("estimated_time", 0.0) << " s)\n";
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
