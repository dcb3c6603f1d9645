// Objects the kernel must never destroy because plugin code may still be running with them (a call that never
// returned: a hung start(), halt() or on_estop()). They stay reachable from a global list, so a leak checker does
// not report them as leaks at exit: they are kept on purpose.
#pragma once

#include <memory>
#include <mutex>
#include <vector>

namespace rcand {

namespace detail {
inline std::mutex& kept_forever_mutex() {
  static std::mutex mutex;
  return mutex;
}
inline std::vector<const void*>& kept_forever() {
  static auto* list = new std::vector<const void*>();  // never freed: it must outlive every static destructor
  return *list;
}
}  // namespace detail

// Takes `object` out of its owner without destroying it, ever.
template <class T> void keep_forever(std::unique_ptr<T>& object) noexcept {
  if (!object) return;
  try {
    std::lock_guard lock(detail::kept_forever_mutex());
    detail::kept_forever().push_back(object.get());
  } catch (...) {  // no memory to record it: it is still never destroyed
  }
  (void)object.release();
}

}  // namespace rcand
