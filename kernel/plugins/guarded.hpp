// THE trampoline for every call into plugin code (register, factories, start, handlers, hooks): exceptions
// never cross the plugin boundary into the kernel.
#pragma once

#include <spdlog/spdlog.h>

#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

#include "kernel/safety/instance_health.hpp"

namespace rcand::kernel {

// The spdlog logger "kernel.plugins"; created from the default logger's sinks when nobody registered it.
// Never null, never throws.
std::shared_ptr<spdlog::logger> plugins_logger() noexcept;

namespace detail {
// Logs "<who>: <what> threw: <message>" and stores why (`exception`, when there is one: fault_of() it), the reason
// bounded (1,000 bytes, valid UTF-8); never throws (falls back to an empty reason).
void record_plugin_throw(std::string_view who, std::string_view what, Fault& failure, std::string_view message,
                         const std::exception* exception = nullptr) noexcept;
}  // namespace detail

// Runs fn(); on a throw of any type logs "<who>: <what> threw: <message>" on "kernel.plugins", stores why in
// `failure` and returns false. Returns true (leaving `failure` untouched) when fn returns.
template <class F> bool guarded_call(std::string_view who, std::string_view what, Fault& failure, F&& fn) noexcept {
  try {
    std::forward<F>(fn)();
    return true;
  } catch (const std::exception& e) {
    detail::record_plugin_throw(who, what, failure, e.what(), &e);
  } catch (const char* text) {
    detail::record_plugin_throw(who, what, failure, text != nullptr ? text : "(null message)");
  } catch (const std::string& text) {
    detail::record_plugin_throw(who, what, failure, text);
  } catch (...) {
    detail::record_plugin_throw(who, what, failure, "unknown exception (not derived from std::exception)");
  }
  return false;
}

// The same, keeping only the reason.
template <class F> bool guarded_call(std::string_view who, std::string_view what, std::string& failure, F&& fn) noexcept {
  Fault fault;
  if (guarded_call(who, what, fault, std::forward<F>(fn))) return true;
  failure.swap(fault.reason);
  return false;
}

// guarded_call for a function that returns a value: the value, or nullopt after a throw (same logging).
template <class Failure, class F, class R = std::invoke_result_t<F>>
std::optional<R> guarded_result(std::string_view who, std::string_view what, Failure& failure, F&& fn) noexcept {
  static_assert(!std::is_void_v<R>, "use guarded_call for functions returning void");
  std::optional<R> result;
  // Moving the value into place may itself throw; that happens inside the guard too.
  guarded_call(who, what, failure, [&] { result.emplace(std::forward<F>(fn)()); });
  return result;
}

}  // namespace rcand::kernel
