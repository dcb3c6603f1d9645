// rcand's side of sdk::RequestDispatcher (rcand/sdk/request_dispatcher.hpp): a plugin's request on behalf of a caller
// runs through Api::execute, so it meets the same route table, scope check, audit entry and e-stop pre-check as HTTP.
// The plugin's audit note is checked here (the rules are the SDK's) before it reaches the audit log.
#pragma once

#include <rcand/sdk/request_dispatcher.hpp>

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
