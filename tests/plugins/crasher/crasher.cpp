// Process isolation fixture (tests/integration/isolation_test.cpp): capability org.rcand.test.crasher, declared
// `isolation: process` in its manifest, so it runs in rcand-plugin-host. Its routes:
//   GET  /pid     the process it runs in, and the latch as its context mirrors it
//   POST /drive   the first differential drive at half speed, through the context's motion gate (rcand's gate)
//   POST /crash   {"how": segfault | abort | leak | spin | close | throw} - dies, grows until its memory limit, never
//                 returns, closes its end of the channel (descriptor 3), or throws (a 500; the process lives on)
//   POST /try     {"what": read_rcand | signal_rcand | signal_group | inet_socket | unix_socket | open, "path",
//                 "read_only"} - what the host's sandbox refuses, each tried harmlessly (signal 0, one byte read, a
//                 file opened and closed); answers the errno (0: allowed)
//   GET  /privileges  NoNewPrivs, CapEff and CapBnd of its process (/proc/self/status)
//   POST /flood   {"calls": N} in the background: one thread halts the first drive (a slow halt holds rcand's side),
//                 then N threads read its status at once; GET /flood: {"finished", "ok", "refused" (rcand's in-flight
//                 cap, named), "other"}
// It publishes a status on start, counts its on_estop() calls there, and logs its shutdown().
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <fstream>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "../fixture.hpp"

namespace {

using rcand::sdk::Json;
using rcand::sdk::Request;
using rcand::sdk::Response;
using rcand::sdk::Route;

[[noreturn]] void crash(const std::string& how) {
  if (how == "segfault") {
    // The kernel's default action, as in a build without sanitizers (whose SIGSEGV handler would report and abort):
    // set through the system call itself, which no sanitizer intercepts.
    struct kernel_sigaction {
      void (*handler)(int);
      unsigned long flags;
      void (*restorer)();
      unsigned long mask;
    } default_action{SIG_DFL, 0, nullptr, 0};
    ::syscall(SYS_rt_sigaction, SIGSEGV, &default_action, nullptr, sizeof default_action.mask);
    volatile int* nowhere = nullptr;
    *nowhere = 1;
  }
  if (how == "abort") std::abort();
  if (how == "leak") {
    std::vector<char*> kept;
    for (;;) {  // 1 MB a millisecond, every page touched, never freed: rcand ends it at its isolation_memory_mb
      char* block = static_cast<char*>(std::malloc(1 << 20));
      if (block == nullptr) std::abort();
      std::memset(block, 1, 1 << 20);
      kept.push_back(block);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  for (volatile bool spin = true; spin;) {  // "spin": never returns
  }
  std::abort();
}

class Crasher final : public rcand::sdk::Capability {
 public:
  explicit Crasher(rcand::sdk::PluginContext& context) : context_(context) {}

  void start() override {
    if (context_.config().get_or<bool>("crash_on_start", false)) crash("segfault");
    context_.publish_status({{"estops", 0}});
  }

  std::vector<Route> routes() override {
    Route pid = rcand::test::get_route("/pid", [this](const Request&) {
      return Response::ok({{"pid", ::getpid()}, {"latched", context_.estop().latched()}});
    });
    Route drive;
    drive.method = "POST";
    drive.path = "/drive";
    drive.motion = true;
    drive.handler = [this](const Request&) {
      const auto actuator = context_.motion().first_actuator(rcand::sdk::DifferentialDrive::kInterface);
      if (!actuator) return Response::error(503, "UNAVAILABLE", "no differential drive");
      const auto status = context_.motion().actuate_as<rcand::sdk::DifferentialDrive>(
          *actuator, [](rcand::sdk::DifferentialDrive& drive) { drive.set_wheel_speeds(0.5, 0.5); });
      return status == rcand::sdk::GateStatus::Ok ? Response::ok({{"moving", *actuator}})
                                                  : rcand::sdk::gate_refusal(status, *actuator);
    };
    Route crash_route;
    crash_route.method = "POST";
    crash_route.path = "/crash";
    crash_route.handler = [](const Request& request) -> Response {
      const std::string how = request.body.is_object() ? request.body.value("how", "") : "";
      if (how == "throw") throw std::runtime_error("the crasher throws, as asked");
      if (how == "close") {
        ::close(3);  // the host's end of its channel to rcand
        return Response::ok({{"closed", true}});
      }
      if (how != "segfault" && how != "abort" && how != "leak" && how != "spin")
        return Response::bad_request("how", "unknown crash");
      crash(how);
    };
    Route attempt;
    attempt.method = "POST";
    attempt.path = "/try";
    attempt.handler = [](const Request& request) {
      const std::string what = request.body.is_object() ? request.body.value("what", "") : "";
      errno = 0;
      if (what == "read_rcand") {
        char byte = 0, source = 0;
        iovec local{&byte, 1}, remote{&source, 1};  // its own address, read in rcand: harmless either way
        (void)::process_vm_readv(::getppid(), &local, 1, &remote, 1, 0);
      } else if (what == "signal_rcand") {
        (void)::kill(::getppid(), 0);  // signal 0: only the permission check
      } else if (what == "signal_group") {
        (void)::kill(0, 0);
      } else if (what == "inet_socket" || what == "unix_socket") {
        const int fd = ::socket(what == "inet_socket" ? AF_INET : AF_UNIX, SOCK_STREAM, 0);
        if (fd >= 0) ::close(fd);
      } else if (what == "open") {
        const int mode = request.body.value("read_only", false) ? O_RDONLY : O_RDWR;
        const int fd = ::open(request.body.value("path", "").c_str(), mode | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        if (fd >= 0) ::close(fd);
      } else {
        return Response::bad_request("what", "unknown attempt");
      }
      return Response::ok({{"errno", errno}});
    };
    Route privileges = rcand::test::get_route("/privileges", [](const Request&) {
      Json out = Json::object();
      std::ifstream status("/proc/self/status");
      for (std::string line; std::getline(status, line);)
        for (const char* key : {"NoNewPrivs", "CapEff", "CapBnd", "Seccomp"})
          if (line.rfind(std::string(key) + ":", 0) == 0)
            out[key] = line.substr(line.find_first_not_of(" \t", std::strlen(key) + 1));
      return Response::ok(out);
    });
    Route flood;
    flood.method = "POST";
    flood.path = "/flood";
    flood.handler = [this](const Request& request) {
      const auto actuator = context_.motion().first_actuator(rcand::sdk::DifferentialDrive::kInterface);
      if (!actuator || flooder_.joinable()) return Response::error(409, "CONFLICT", "no drive, or flooded once already");
      flooder_ = std::thread([this, id = *actuator, calls = request.body.value("calls", 100)] { flood_calls(id, calls); });
      return Response::ok({{"started", true}});
    };
    Route flooded = rcand::test::get_route("/flood", [this](const Request&) {
      return Response::ok({{"finished", flood_finished_.load()},
                           {"ok", flood_ok_.load()},
                           {"refused", flood_refused_.load()},
                           {"other", flood_other_.load()}});
    });
    return {pid, drive, crash_route, attempt, privileges, flood, flooded};
  }

  Json status() const override { return {{"estops", estops_.load()}}; }
  void shutdown() noexcept override {
    if (flooder_.joinable()) flooder_.join();
    context_.log().info("crasher shutdown() ran in process ", ::getpid());
  }
  void on_estop() noexcept override {
    ++estops_;
    context_.publish_status({{"estops", estops_.load()}});
  }

 private:
  void flood_calls(const std::string& actuator, int calls) {
    auto& motion = context_.motion();
    std::thread slow_halt([&] { motion.actuate(actuator, [](rcand::sdk::ActuatorDriver& drive) { drive.halt(); }); });
    std::vector<std::thread> readers;
    for (int i = 0; i < calls; ++i)
      readers.emplace_back([&] {
        try {
          motion.inspect(actuator, [](const rcand::sdk::ActuatorDriver& drive) { (void)drive.status(); });
          ++flood_ok_;
        } catch (const std::exception& e) {
          ++(std::string(e.what()).find("calls in flight") != std::string::npos ? flood_refused_ : flood_other_);
        }
      });
    for (auto& reader : readers) reader.join();
    slow_halt.join();
    flood_finished_ = true;
  }

  rcand::sdk::PluginContext& context_;
  std::atomic<int> estops_{0};
  std::thread flooder_;
  std::atomic<int> flood_ok_{0}, flood_refused_{0}, flood_other_{0};
  std::atomic<bool> flood_finished_{false};
};

void register_crasher(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.crasher", true},
                           [](rcand::sdk::PluginContext& context) { return std::make_unique<Crasher>(context); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.crasher", "1.0.0", register_crasher)
