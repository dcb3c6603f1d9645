// Fault drill fixture: capability org.rcand.test.faulty (GET /ok, POST /work) and actuating driver
// org.rcand.test.faulty_drive, each failing in the one hook its settings name ("hook") in the way they say ("fault"):
//   throw   - throws (from a noexcept hook that means std::terminate; the kernel's crews must contain it)
//   hang    - never returns
//   slow    - returns after slow_ms
//   garbage - returns nonsense the kernel must refuse cleanly (null object, broken routes, invalid status/body)
//   gate    - returns once the test writes a byte to the FIFO its "gate" setting names (or closes it)
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

#include "../fixture.hpp"

namespace {

using rcand::sdk::Json;
using rcand::sdk::Request;
using rcand::sdk::Response;
using rcand::sdk::Route;

struct Fault {
  std::string hook = "none", kind = "throw", gate;
  int slow_ms = 2000;

  explicit Fault(rcand::sdk::PluginContext& context) {
    const auto& settings = context.config();
    hook = settings.get_or<std::string>("hook", "none");
    kind = settings.get_or<std::string>("fault", "throw");
    slow_ms = settings.get_or<int>("slow_ms", 2000);
    gate = settings.get_or<std::string>("gate", "");
  }
  bool in(std::string_view name) const { return hook == name; }
  bool garbage(std::string_view name) const { return in(name) && kind == "garbage"; }
  // Throws, hangs or sleeps when `name` is the faulty hook (garbage is the caller's business).
  void strike(std::string_view name) const {
    if (!in(name)) return;
    if (kind == "throw") throw std::runtime_error("fault drill: " + hook + " throws");
    if (kind == "hang")
      for (;;) std::this_thread::sleep_for(std::chrono::hours(1));
    if (kind == "slow") std::this_thread::sleep_for(std::chrono::milliseconds(slow_ms));
    if (kind == "gate") {  // blocks in open() until the test opens the FIFO for writing, then in read() until it writes
      const int fd = ::open(gate.c_str(), O_RDONLY | O_CLOEXEC);
      if (fd < 0) throw std::runtime_error("fault drill: cannot open the gate " + gate);
      char byte = 0;
      [[maybe_unused]] const ssize_t n = ::read(fd, &byte, 1);
      ::close(fd);
    }
  }
};

// For hooks declared noexcept: the throw happens in a callee, as it would in real driver code.
void strike_noexcept(const Fault& fault, std::string_view name) noexcept { fault.strike(name); }

Json invalid_utf8() { return Json{{"text", std::string("\xff\xfe garbage \xc3", 12)}}; }

class FaultyCapability final : public rcand::sdk::Capability {
 public:
  explicit FaultyCapability(const Fault& fault) : fault_(fault) {}
  void start() override { fault_.strike("start"); }
  std::vector<Route> routes() override {
    fault_.strike("routes");
    if (fault_.garbage("routes")) {
      Route no_handler;
      no_handler.method = "POST";
      no_handler.path = "/work";
      Route no_method;
      no_method.path = "relative";
      no_method.handler = [](const Request&) { return Response::ok(); };
      return {no_handler, no_method, no_handler};
    }
    Route ok = rcand::test::get_route("/ok", [](const Request&) { return Response::ok({{"ok", true}}); });
    Route work;
    work.method = "POST";
    work.path = "/work";
    work.handler = [this](const Request&) -> Response {
      fault_.strike("handler");
      if (fault_.garbage("handler")) return Response{999, invalid_utf8()};
      return Response::ok({{"worked", true}});
    };
    return {ok, work};
  }
  Json status() const override {
    fault_.strike("status");
    if (fault_.garbage("status")) return invalid_utf8();
    // "injected", not "fault": a top-level "fault" reports the instance in error (sdk/capability.hpp), and the drills
    // check the kernel's own verdict (ok or failed).
    return {{"hook", fault_.hook}, {"injected", fault_.kind}};
  }
  void on_estop() noexcept override { strike_noexcept(fault_, "on_estop"); }
  void shutdown() noexcept override { strike_noexcept(fault_, "shutdown"); }

 private:
  const Fault fault_;
};

class FaultyDrive final : public rcand::sdk::DifferentialDrive {
 public:
  explicit FaultyDrive(const Fault& fault) : fault_(fault) {}
  void start() override { fault_.strike("start"); }
  void set_wheel_speeds(double, double) override {}
  void halt() noexcept override { strike_noexcept(fault_, "halt"); }
  Json status() const override {
    fault_.strike("status");
    if (fault_.garbage("status")) return Json(std::numeric_limits<double>::quiet_NaN());
    // "injected", not "fault": a top-level "fault" reports the instance in error (sdk/capability.hpp), and the drills
    // check the kernel's own verdict (ok or failed).
    return {{"hook", fault_.hook}, {"injected", fault_.kind}};
  }
  void shutdown() noexcept override { strike_noexcept(fault_, "shutdown"); }

 private:
  const Fault fault_;
};

template <class Object> std::unique_ptr<Object> make(rcand::sdk::PluginContext& context) {
  Fault fault(context);
  fault.strike("factory");
  if (fault.garbage("factory")) return nullptr;
  return std::make_unique<Object>(fault);
}

void register_faulty(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.faulty", false},
                           [](rcand::sdk::PluginContext& context) { return make<FaultyCapability>(context); });
  registrar.add_driver({"org.rcand.test.faulty_drive", true, std::string(rcand::sdk::DifferentialDrive::kInterface)},
                       [](rcand::sdk::PluginContext& context) { return make<FaultyDrive>(context); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.test.faulty", "1.0.0", register_faulty)
