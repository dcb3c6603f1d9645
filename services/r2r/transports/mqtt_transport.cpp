#include "services/r2r/transports/mqtt_transport.hpp"

#include <mosquitto.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>

#include "libs/base/file_exposure.hpp"
#include "services/r2r/transports/message_peek.hpp"

namespace rcand::services::r2r {
namespace {

std::once_flag library_once;

std::string first_line_of(const std::filesystem::path& file, const std::string& key) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(key + ": cannot read " + file.string());
  std::string line;
  std::getline(in, line);
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
  if (line.empty()) throw std::runtime_error(key + ": " + file.string() + " is empty");
  return line;
}

std::filesystem::path resolve(const nlohmann::json& value, const std::filesystem::path& base_dir, const std::string& key) {
  if (!value.is_string() || value.get_ref<const std::string&>().empty())
    throw std::invalid_argument(key + ": expected a non-empty file path");
  std::filesystem::path path = value.get<std::string>();
  return path.is_absolute() ? path : base_dir / path;
}

}  // namespace

MqttOptions mqtt_options_from_config(const nlohmann::json& mqtt, const std::string& robot_name,
                                     const std::filesystem::path& base_dir) {
  const std::string at = "runtime.r2r.mqtt";
  if (!mqtt.is_object()) throw std::invalid_argument(at + ": expected a mapping");
  MqttOptions options;
  options.robot_name = robot_name;
  auto text = [&](const char* key) -> std::optional<std::string> {
    if (!mqtt.contains(key) || mqtt[key].is_null()) return std::nullopt;
    if (!mqtt[key].is_string() || mqtt[key].get_ref<const std::string&>().empty())
      throw std::invalid_argument(at + "." + key + ": expected a non-empty string");
    return mqtt[key].get<std::string>();
  };
  auto file = [&](const nlohmann::json& block, const char* key,
                  const std::string& where) -> std::optional<std::filesystem::path> {
    if (!block.contains(key) || block[key].is_null()) return std::nullopt;
    return resolve(block[key], base_dir, where + "." + key);
  };
  if (auto host = text("host")) options.host = *host;
  if (mqtt.contains("port")) {
    const auto& port = mqtt["port"];
    if (!port.is_number_integer() || port.get<long long>() < 1 || port.get<long long>() > 65535)
      throw std::invalid_argument(at + ".port: expected an integer from 1 to 65535");
    options.port = static_cast<std::uint16_t>(port.get<int>());
  }
  if (mqtt.contains("keepalive_s")) {
    const auto& keepalive = mqtt["keepalive_s"];
    if (!keepalive.is_number_integer() || keepalive.get<long long>() < 5 || keepalive.get<long long>() > 65535)
      throw std::invalid_argument(at + ".keepalive_s: expected an integer from 5 to 65535");
    options.keepalive_s = keepalive.get<int>();
  }
  options.username = text("username");
  if (auto id = text("client_id")) options.client_id = *id;
  options.password_file = file(mqtt, "password_file", at);
  options.token_file = file(mqtt, "token_file", at);
  if (options.password_file && options.token_file)
    throw std::invalid_argument(at + ": set password_file or token_file, not both");
  if (mqtt.contains("status_subscriptions") && !mqtt["status_subscriptions"].is_null()) {
    const auto& wanted = mqtt["status_subscriptions"];
    const std::string key = at + ".status_subscriptions";
    if (wanted.is_string() && wanted == "all") {
      options.status_of_all = true;
    } else if (wanted.is_array()) {
      for (const auto& name : wanted) {
        // A name, not a pattern: a wildcard would subscribe to more than that robot.
        if (!name.is_string() || name.get_ref<const std::string&>().empty() ||
            name.get_ref<const std::string&>().find_first_of(std::string_view("+#\0", 3)) != std::string::npos)
          throw std::invalid_argument(key + ": expected robot names (no '+' or '#'), or all");
        options.status_subscriptions.push_back(name.get<std::string>());
      }
    } else {
      throw std::invalid_argument(key + ": expected a list of robot names, or all");
    }
  }
  if (mqtt.contains("tls") && !mqtt["tls"].is_null()) {
    const auto& tls = mqtt["tls"];
    if (!tls.is_object()) throw std::invalid_argument(at + ".tls: expected a mapping");
    MqttTls settings;
    auto ca = file(tls, "ca_file", at + ".tls");
    if (!ca) throw std::invalid_argument(at + ".tls.ca_file: required for TLS");
    settings.ca_file = *ca;
    settings.cert_file = file(tls, "cert_file", at + ".tls");
    settings.key_file = file(tls, "key_file", at + ".tls");
    if (settings.cert_file.has_value() != settings.key_file.has_value())
      throw std::invalid_argument(at + ".tls: cert_file and key_file go together");
    options.tls = std::move(settings);
    if (!mqtt.contains("port")) options.port = 8883;
  }
  return options;
}

struct MqttTransport::State {
  explicit State(MqttOptions options_in)
      : options(std::move(options_in)), log(options.log ? options.log : spdlog::default_logger()) {}

  const MqttOptions options;
  const std::shared_ptr<spdlog::logger> log;
  mosquitto* client = nullptr;
  std::string own_topic, broadcast_topic;
  std::string status_topics;     // "r2r/status/": status broadcasts, one topic per robot
  std::string own_status_topic;  // "r2r/status/<own name>": retained, with the last will

  std::mutex offline_mutex;
  std::function<std::string()> offline;  // this robot's `offline` status (the will); may be empty

  std::shared_mutex deliver_mutex;  // shared by deliveries, exclusive in stop()
  Deliver deliver;

  std::atomic<bool> running{false};
  std::atomic<bool> connected{false};
  std::atomic<bool> outage_logged{false};
  mutable std::mutex counters_mutex;
  MqttCounters counters;

  void count(std::uint64_t MqttCounters::*field) {
    std::lock_guard lock(counters_mutex);
    ++(counters.*field);
  }

  std::string offline_status() {
    std::lock_guard lock(offline_mutex);
    return offline ? offline() : std::string();
  }

  // The will goes to the broker in each CONNECT: set afresh before every (re)connect, so its timestamp is the
  // connection's (a reader still sees it age while the robot stays connected: §11.13 says what it does with that).
  void set_will() {
    const std::string will = offline_status();
    if (will.empty()) return;
    mosquitto_will_set(client, own_status_topic.c_str(), static_cast<int>(will.size()), will.data(), 1, true);
  }

  static void on_connect(mosquitto* client, void* self, int rc) {
    auto& state = *static_cast<State*>(self);
    if (rc != 0) {
      if (!state.outage_logged.exchange(true))
        state.log->warn("r2r mqtt: broker {}:{} refused the connection: {} (retrying)", state.options.host, state.options.port,
                        mosquitto_connack_string(rc));
      return;
    }
    state.connected = true;
    state.count(&MqttCounters::connects);
    // Subscriptions are renewed on every connect: a clean session forgets them.
    mosquitto_subscribe(client, nullptr, state.own_topic.c_str(), 1);
    mosquitto_subscribe(client, nullptr, state.broadcast_topic.c_str(), 1);
    for (const auto& topic : state.options.extra_subscriptions) mosquitto_subscribe(client, nullptr, topic.c_str(), 1);
    // Status: QoS 0 like its publishes; a subscription gets each robot's retained (latest, or offline) status at once.
    if (state.options.status_of_all) mosquitto_subscribe(client, nullptr, (state.status_topics + "#").c_str(), 0);
    for (const auto& name : state.options.status_subscriptions)
      mosquitto_subscribe(client, nullptr, (state.status_topics + name).c_str(), 0);
    if (state.outage_logged.exchange(false))
      state.log->info("r2r mqtt: reconnected to {}:{}", state.options.host, state.options.port);
    else state.log->info("r2r mqtt: connected to {}:{} as {}", state.options.host, state.options.port, state.own_topic);
  }

  static void on_disconnect(mosquitto*, void* self, int rc) {
    auto& state = *static_cast<State*>(self);
    state.connected = false;
    state.count(&MqttCounters::disconnects);
    if (state.running) state.set_will();  // the network thread reconnects next: with a will of this moment
    if (rc != 0 && state.running && !state.outage_logged.exchange(true))
      state.log->warn("r2r mqtt: lost the broker {}:{} ({}); reconnecting", state.options.host, state.options.port,
                      mosquitto_strerror(rc));
  }

  static void on_message(mosquitto*, void* self, const mosquitto_message* message) {
    auto& state = *static_cast<State*>(self);
    if (message == nullptr || message->payload == nullptr || message->payloadlen <= 0) return;
    state.count(&MqttCounters::received);
    InboundMessage inbound;
    inbound.bytes.assign(static_cast<const char*>(message->payload), static_cast<std::size_t>(message->payloadlen));
    inbound.transport = "mqtt";
    inbound.peer = message->topic ? message->topic : "";
    inbound.status_topic = inbound.peer.starts_with(state.status_topics);
    inbound.broadcast = inbound.peer == state.broadcast_topic || inbound.status_topic;
    // No reply route: the answer goes out through send() to r2r/<source_id>.
    std::shared_lock lock(state.deliver_mutex);
    if (state.deliver) state.deliver(std::move(inbound));
  }
};

MqttTransport::MqttTransport(MqttOptions options) : state_(std::make_shared<State>(std::move(options))) {}

MqttTransport::~MqttTransport() { stop(); }

void MqttTransport::start(Deliver deliver) {
  State& s = *state_;
  if (s.client != nullptr) return;
  std::call_once(library_once, [] { mosquitto_lib_init(); });
  const auto& o = s.options;
  s.own_topic = o.topic_prefix + "/" + o.robot_name;
  s.broadcast_topic = o.topic_prefix + "/broadcast";
  s.status_topics = o.topic_prefix + "/status/";
  s.own_status_topic = s.status_topics + o.robot_name;
  const std::string client_id = o.client_id.empty() ? "rcand-" + o.robot_name : o.client_id;

  // The broker password or token, with a warning when other users of the machine may read it (as for every secret).
  const auto read_secret = [&s](const std::filesystem::path& file, const std::string& key) {
    std::string secret = first_line_of(file, key);
    if (const auto problem = others_may_access(file, "this secret"); !problem.empty()) s.log->warn("{}: {}", key, problem);
    return secret;
  };
  std::optional<std::string> password;
  if (o.password_file) password = read_secret(*o.password_file, "runtime.r2r.mqtt.password_file");
  if (o.token_file) password = read_secret(*o.token_file, "runtime.r2r.mqtt.token_file");

  s.client = mosquitto_new(client_id.c_str(), true, &s);
  if (s.client == nullptr) throw std::runtime_error("runtime.r2r.mqtt: cannot create the MQTT client");
  auto fail = [&](const std::string& what) {
    mosquitto_destroy(s.client);
    s.client = nullptr;
    throw std::runtime_error(what);
  };
  mosquitto_int_option(s.client, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
  mosquitto_int_option(s.client, MOSQ_OPT_TCP_NODELAY, 1);  // small messages: no Nagle delay on every hop
  if (o.username || password) {
    const std::string user = o.username.value_or(o.robot_name);
    if (mosquitto_username_pw_set(s.client, user.c_str(), password ? password->c_str() : nullptr) != MOSQ_ERR_SUCCESS)
      fail("runtime.r2r.mqtt.username: rejected by libmosquitto");
  }
  if (o.tls) {
    const std::string ca = o.tls->ca_file.string();
    const std::string cert = o.tls->cert_file ? o.tls->cert_file->string() : std::string();
    const std::string key = o.tls->key_file ? o.tls->key_file->string() : std::string();
    const int rc = mosquitto_tls_set(s.client, ca.c_str(), nullptr, cert.empty() ? nullptr : cert.c_str(),
                                     key.empty() ? nullptr : key.c_str(), nullptr);
    if (rc != MOSQ_ERR_SUCCESS)
      fail("runtime.r2r.mqtt.tls: " + std::string(mosquitto_strerror(rc)) + " (check ca_file, cert_file, key_file)");
  }
  mosquitto_connect_callback_set(s.client, &State::on_connect);
  mosquitto_disconnect_callback_set(s.client, &State::on_disconnect);
  mosquitto_message_callback_set(s.client, &State::on_message);
  mosquitto_reconnect_delay_set(s.client, 1, 30, true);
  s.set_will();
  {
    std::unique_lock lock(s.deliver_mutex);
    s.deliver = std::move(deliver);
  }
  s.running = true;
  // A broker that is down now is not fatal: the network thread keeps retrying.
  const int rc = mosquitto_connect_async(s.client, o.host.c_str(), o.port, o.keepalive_s);
  if (rc != MOSQ_ERR_SUCCESS && !s.outage_logged.exchange(true))
    s.log->warn("r2r mqtt: cannot reach the broker {}:{} yet ({}); retrying", o.host, o.port,
                rc == MOSQ_ERR_ERRNO ? std::strerror(errno) : mosquitto_strerror(rc));
  if (const int loop = mosquitto_loop_start(s.client); loop != MOSQ_ERR_SUCCESS) {
    s.running = false;
    fail("runtime.r2r.mqtt: cannot start the MQTT network thread: " + std::string(mosquitto_strerror(loop)));
  }
}

bool MqttTransport::send(const std::string& bytes, const std::optional<std::string>& target_id) {
  State& s = *state_;
  if (!s.running || s.client == nullptr) return false;
  // Any id that is a legal topic suffix gets its messages on r2r/<id>: a RURI id ("rcan://host/acme/arm/u1") spans
  // topic levels, which MQTT allows; wildcards and NUL never reach the broker.
  if (target_id && (target_id->empty() || target_id->find_first_of(std::string_view("+#\0", 3)) != std::string::npos))
    return false;
  // This robot's status goes to its own topic, retained (a subscriber gets the latest at once); a status for one
  // robot (rare: an answer) and everything else as before.
  const bool status = peek_message(bytes).type == "status";
  const bool own_status = status && !target_id;
  const std::string topic = target_id    ? s.options.topic_prefix + "/" + *target_id
                            : own_status ? s.own_status_topic
                                         : s.broadcast_topic;
  if (mosquitto_pub_topic_check(topic.c_str()) != MOSQ_ERR_SUCCESS) return false;
  const int qos = status ? 0 : 1;
  const int rc =
      mosquitto_publish(s.client, nullptr, topic.c_str(), static_cast<int>(bytes.size()), bytes.data(), qos, own_status);
  // QoS 1 while disconnected is queued by libmosquitto and sent after the reconnect.
  const bool ok = rc == MOSQ_ERR_SUCCESS || (rc == MOSQ_ERR_NO_CONN && qos > 0);
  s.count(ok ? &MqttCounters::published : &MqttCounters::publish_failed);
  return ok;
}

void MqttTransport::stop() noexcept {
  State& s = *state_;
  {
    std::unique_lock lock(s.deliver_mutex);
    s.deliver = nullptr;
  }
  if (s.client == nullptr) return;
  // A clean DISCONNECT discards the will: say `offline` ourselves, queued ahead of the DISCONNECT (one ordered queue).
  if (s.running && s.connected) {
    const std::string offline = s.offline_status();
    if (!offline.empty())
      mosquitto_publish(s.client, nullptr, s.own_status_topic.c_str(), static_cast<int>(offline.size()), offline.data(), 0, true);
  }
  s.running = false;
  mosquitto_disconnect(s.client);
  mosquitto_loop_stop(s.client, false);
  mosquitto_destroy(s.client);
  s.client = nullptr;
  s.connected = false;
}

void MqttTransport::set_offline_status(std::function<std::string()> offline) {
  std::lock_guard lock(state_->offline_mutex);
  state_->offline = std::move(offline);
}

bool MqttTransport::connected() const noexcept { return state_->connected; }

MqttCounters MqttTransport::counters() const {
  std::lock_guard lock(state_->counters_mutex);
  return state_->counters;
}

}  // namespace rcand::services::r2r
