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

namespace rcand::kernel {

// The spdlog logger "kernel.plugins"; created from the default logger's sinks when nobody registered it.
// Never null, never throws.
std::shared_ptr<spdlog::logger> plugins_logger() noexcept;

namespace detail {
// Logs "<who>: <what> threw: <message>" and stores the message (bounded: 1,000 bytes, valid UTF-8); never throws.
void record_plugin_throw(std::string_view who, std::string_view what, std::string& failure, std::string_view message) noexcept;
}  // namespace detail

// Runs fn(); on a throw of any type logs "<who>: <what> threw: <message>" on "kernel.plugins", copies the
// message (bounded) into `failure` and returns false. Returns true (leaving `failure` untouched) when fn returns.
template <class F> bool guarded_call(std::string_view who, std::string_view what, std::string& failure, F&& fn) noexcept {
  try {
    std::forward<F>(fn)();
    return true;
  } catch (const std::exception& e) {
    detail::record_plugin_throw(who, what, failure, e.what());
  } catch (const char* text) {
    detail::record_plugin_throw(who, what, failure, text != nullptr ? text : "(null message)");
  } catch (const std::string& text) {
    detail::record_plugin_throw(who, what, failure, text);
  } catch (...) {
    detail::record_plugin_throw(who, what, failure, "unknown exception (not derived from std::exception)");
  }
  return false;
}

// guarded_call for a function that returns a value: the value, or nullopt after a throw (same logging).
template <class F, class R = std::invoke_result_t<F>>
std::optional<R> guarded_result(std::string_view who, std::string_view what, std::string& failure, F&& fn) noexcept {
  static_assert(!std::is_void_v<R>, "use guarded_call for functions returning void");
  std::optional<R> result;
  // Moving the value into place may itself throw; that happens inside the guard too.
  guarded_call(who, what, failure, [&] { result.emplace(std::forward<F>(fn)()); });
  return result;
}

}  // namespace rcand::kernel
