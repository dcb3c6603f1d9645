#include "kernel/plugins/guarded.hpp"

#include <doctest/doctest.h>

#include <spdlog/sinks/ostream_sink.h>

#include <sstream>
#include <stdexcept>

using rcand::kernel::guarded_call;
using rcand::kernel::guarded_result;

namespace {
struct NotAnException {
  int code;
};
}  // namespace

TEST_CASE("guarded_call runs the function and reports success") {
  std::string failure = "untouched";
  int calls = 0;
  CHECK(guarded_call("org.x", "start", failure, [&] { ++calls; }));
  CHECK(calls == 1);
  CHECK(failure == "untouched");
}

TEST_CASE("guarded_call catches std::exception, copies the message and logs who and what") {
  std::ostringstream captured;
  auto logger = rcand::kernel::plugins_logger();
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(captured);
  logger->sinks().push_back(sink);
  std::string failure;
  CHECK_FALSE(guarded_call("org.x", "register", failure, [] { throw std::runtime_error("boom 42"); }));
  logger->flush();
  logger->sinks().pop_back();
  CHECK(failure == "boom 42");
  CHECK(captured.str().find("org.x: register threw: boom 42") != std::string::npos);
}

TEST_CASE("guarded_call catches non-std throws") {
  std::string failure;
  CHECK_FALSE(guarded_call("org.x", "handler", failure, [] { throw NotAnException{7}; }));
  CHECK(failure.find("unknown exception") != std::string::npos);
  CHECK_FALSE(guarded_call("org.x", "handler", failure, [] { throw 42; }));
  CHECK(failure.find("unknown exception") != std::string::npos);
  CHECK_FALSE(guarded_call("org.x", "handler", failure, [] { throw "a C string"; }));
  CHECK(failure == "a C string");
  CHECK_FALSE(guarded_call("org.x", "handler", failure, [] { throw std::string("a std::string"); }));
  CHECK(failure == "a std::string");
}

TEST_CASE("guarded_result returns the value, or nullopt after a throw") {
  std::string failure;
  const auto value = guarded_result("org.x", "factory", failure, [] { return std::make_unique<int>(5); });
  REQUIRE(value.has_value());
  CHECK(**value == 5);
  CHECK(failure.empty());

  const auto none = guarded_result("org.x", "factory", failure, []() -> int { throw std::logic_error("no int"); });
  CHECK_FALSE(none.has_value());
  CHECK(failure == "no int");
}

TEST_CASE("plugins_logger is the registered kernel.plugins logger") {
  auto logger = rcand::kernel::plugins_logger();
  REQUIRE(logger != nullptr);
  CHECK(logger->name() == "kernel.plugins");
  CHECK(spdlog::get("kernel.plugins") == logger);
}
