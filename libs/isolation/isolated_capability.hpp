// A capability whose plugin runs in a process of its own (`isolation: process`, issue 34), as rcand sees it: an
// sdk::Capability like any other, so the kernel's routes, status, stop path and shutdown treat it as they treat one in
// process. Its start() starts rcand-plugin-host, which opens the same plugin through the same loader checks and runs
// the capability there (host_session.hpp); routes forward each request over the channel, and the host's calls on
// actuators go through this process's motion gate (actuator_calls.hpp), so the latch, the epoch and the scope stay
// checked here.
//
// When the host process ends (a segfault, an abort, a kill) or stops answering (its heartbeat, a request past its
// time, memory over its limit, in which cases rcand kills it), every actuator the capability moved is halted at once,
// its routes answer 503 with the reason, its status shows the fault, the death is audited, and the host is started
// again after a backoff (100 ms doubling to 5 s; back to 100 ms after a life of 30 s). Five deaths within a minute
// are a crash loop: the capability is then failed with the last reason, and not started again until rcand restarts.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "libs/base/worker_thread.hpp"
#include "libs/isolation/channel.hpp"
#include "libs/isolation/frame_ring.hpp"
#include "libs/isolation/remote_dispatcher.hpp"
#include "libs/isolation/remote_obstacles.hpp"
#include "libs/isolation/stream_relay.hpp"
#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/context.hpp"
#include "rcand/sdk/contract/isolation.hpp"

namespace rcand::isolation {

// What the host process runs, and its limits.
struct HostSpec {
  std::filesystem::path binary;           // rcand-plugin-host (find_host_binary)
  std::vector<std::string> plugin_paths;  // rcand's plugin search path: the host finds the plugin as rcand did
  std::string plugin_id;
  sdk::contract::Isolation isolation;               // memory_mb (past it the host is killed) and the sandbox's needs
  std::vector<std::string> hidden;                  // rcand's own files, out of the host's reach (config::private_files)
  std::chrono::milliseconds request_timeout{4750};  // under the kernel's handler timeout, which would fail it for good
  std::chrono::milliseconds start_timeout{9500};    // the plugin's factory, start() and routes(), in the host
};

// What the kernel learns of the host's life: an audit entry (event, detail) per death, and the instance failed once
// the host is in a crash loop.
struct HostEvents {
  std::function<void(const std::string& event, const std::string& detail)> audit;
  std::function<void(const std::string& reason)> fail;
};

class IsolatedCapability final : public sdk::Capability {
 public:
  static constexpr std::chrono::milliseconds kHeartbeat{200};
  static constexpr std::chrono::milliseconds kHeartbeatLimit{3000};
  static constexpr std::chrono::milliseconds kFirstBackoff{100};
  static constexpr std::chrono::milliseconds kMaxBackoff{5000};
  static constexpr std::chrono::seconds kStableLife{30};
  static constexpr int kCrashLoopDeaths = 5;
  static constexpr std::chrono::seconds kCrashLoopWindow{60};
  static constexpr std::chrono::milliseconds kStatusWait{150};
  static constexpr int kMaxCallsInFlight = 64;

  IsolatedCapability(sdk::PluginContext& context, HostSpec spec, HostEvents events);
  ~IsolatedCapability() override;

  // The first host started and its capability up, or throws what went wrong there (the instance then fails).
  void start() override;
  std::vector<sdk::Route> routes() override;
  std::vector<sdk::StreamRoute> stream_routes() override;
  sdk::Json status() const override;
  void on_estop() noexcept override;
  void shutdown() noexcept override;

 private:
  struct Host {
    pid_t pid = 0;
    std::shared_ptr<Channel> channel;
    std::shared_ptr<FrameRing> ring;  // its frames (stream_frames.hpp)
    std::thread reader;
    bool gone = false;  // its channel closed: the process ended or is ending
    std::chrono::steady_clock::time_point started, last_pong;
  };

  void spawn();  // under mutex_
  void read(std::shared_ptr<Channel> channel, std::shared_ptr<FrameRing> ring);
  void handle(const nlohmann::json& message, const std::shared_ptr<Channel>& channel, FrameRing* ring);
  void answer_call(const nlohmann::json& call, const std::shared_ptr<Channel>& channel);
  void supervise();
  void check_alive();  // under mutex_
  void bury(std::unique_lock<std::mutex>& lock);
  void end_host(std::unique_lock<std::mutex>& lock);
  static std::string close_and_reap(Host& host);
  void kill_host(const std::string& why);
  // A request to the host's route (or, with `stream`, to its stream route, for the client's writer of that id); the
  // answer, or 503 with the reason. A stream handler's answer is status 0: it returned.
  sdk::Response forward(std::size_t route, const sdk::Request& request, std::optional<std::uint64_t> stream = std::nullopt);
  void open_stream(std::size_t route, const sdk::Request& request, std::shared_ptr<sdk::StreamWriter> writer);
  sdk::Response unavailable() const;                         // under mutex_
  nlohmann::json with_process(nlohmann::json status) const;  // under mutex_
  nlohmann::json down_status() const;                        // under mutex_: the fault while no host serves
  void halt_moved(const std::set<std::string>& moved) noexcept;
  nlohmann::json with_pose(nlohmann::json message) const;  // rcand's pose reading added, when it has a pose source

  sdk::PluginContext& context_;
  const HostSpec spec_;
  const HostEvents events_;
  WorkerThread calls_;  // the host's calls on actuators, one at a time, in order
  StreamRelay streams_;
  CredentialTable credentials_;  // of the requests sent to the host
  RemoteObstacles obstacles_;
  bool obstacles_offered_ = false;  // on the calls worker
  std::atomic<int> calls_in_flight_{0};

  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  Host host_;
  bool up_ = false, stopping_ = false, failed_ = false;
  std::uint64_t generation_ = 0;  // one more for each host that ended
  std::string down_reason_, kill_reason_, start_error_;
  std::optional<nlohmann::json> route_specs_;  // {"routes","streams"} the first host's capability serves; later ones agree
  nlohmann::json sandbox_ = nlohmann::json::object();  // what its host's sandbox enforces on devices (its own word)
  mutable std::uint64_t next_id_ = 0;
  struct Answer {
    sdk::Response response;
    std::optional<std::string> threw;  // what its handler threw, if it did
  };
  std::map<std::uint64_t, std::optional<Answer>> requests_;
  mutable std::map<std::uint64_t, std::optional<nlohmann::json>> statuses_;
  std::set<std::string> moved_;  // actuators a call of this capability moved
  int restarts_ = 0;
  std::chrono::milliseconds backoff_{0};
  std::chrono::steady_clock::time_point restart_at_;
  std::deque<std::chrono::steady_clock::time_point> deaths_;
  std::thread supervisor_;
};

}  // namespace rcand::isolation
