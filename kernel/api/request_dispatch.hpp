// rcand's side of sdk::RequestDispatcher (rcand/sdk/interfaces/request_dispatcher.hpp): a plugin's request on behalf of a caller
// runs through Api::execute_for_caller with the caller's own credential (the CallerCredential the kernel attached to
// the request the plugin acts for), so it is authenticated again and meets the same route table, scope check, audit
// entry and e-stop pre-check as that caller's HTTP request would now. The plugin's audit note is checked here (the
// rules are the SDK's) before it reaches the audit log.
#pragma once

#include <rcand/sdk/interfaces/request_dispatcher.hpp>

#include "kernel/api/api.hpp"

namespace rcand::kernel {

class KernelRequestDispatcher final : public sdk::RequestDispatcher {
 public:
  explicit KernelRequestDispatcher(Api& api) : api_(api) {}
  void dispatch(sdk::Request request, sdk::Json audit_note, std::function<void(sdk::Response)> done) const noexcept override;

 private:
  Api& api_;
};

}  // namespace rcand::kernel
