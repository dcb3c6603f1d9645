// A plugin that throws out of a noexcept hook (halt(), on_estop(), shutdown()) makes C++ call std::terminate, which
// would take the whole robot down. On threads that exist only to make such calls (the stop path's crews), a trap turns
// that into a reported failure of the one call: the thread reports what was thrown and then parks for good (the plugin
// frames below it never unwound, so it must never run again); the process keeps serving. Threads without an armed trap
// keep the normal behaviour (the previous handler, then abort).
#pragma once

#include <functional>
#include <string_view>

namespace rcand {

class TerminateTrap {
 public:
  // Called on the trapped thread with the thrown exception's message; must not throw.
  using Report = std::function<void(std::string_view what)>;

  // Arms the calling thread until destruction (installs the process-wide handler on first use).
  explicit TerminateTrap(Report report);
  ~TerminateTrap();
  TerminateTrap(const TerminateTrap&) = delete;
  TerminateTrap& operator=(const TerminateTrap&) = delete;

 private:
  Report report_;
};

}  // namespace rcand
