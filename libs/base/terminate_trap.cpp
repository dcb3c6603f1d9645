#include "libs/base/terminate_trap.hpp"

#include <chrono>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <string>
#include <thread>

namespace rcand {
namespace {

thread_local TerminateTrap::Report* armed_report = nullptr;
std::terminate_handler previous_handler = nullptr;
std::once_flag installed;

std::string current_exception_message() noexcept {
  try {
    if (auto error = std::current_exception()) std::rethrow_exception(error);
    return "std::terminate was called";
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "an exception not derived from std::exception";
  }
}

[[noreturn]] void on_terminate() {
  if (auto* report = armed_report) {
    armed_report = nullptr;  // a second terminate on this thread (the report itself failing) takes the normal path
    (*report)(current_exception_message());
    for (;;) std::this_thread::sleep_for(std::chrono::hours(24));  // parked: see the header
  }
  if (previous_handler != nullptr) previous_handler();
  std::abort();
}

}  // namespace

TerminateTrap::TerminateTrap(Report report) : report_(std::move(report)) {
  std::call_once(installed, [] { previous_handler = std::set_terminate(on_terminate); });
  armed_report = &report_;
}

TerminateTrap::~TerminateTrap() { armed_report = nullptr; }

}  // namespace rcand
