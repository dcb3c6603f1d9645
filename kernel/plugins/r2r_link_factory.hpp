// Where a plugin's R2R link comes from (sdk::PluginContext::r2r()): offered by the R2R service when it is enabled,
// so the kernel hands links out without knowing the service.
#pragma once

#include <memory>
#include <string>

#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::kernel {

class R2rLinkFactory {
 public:
  virtual ~R2rLinkFactory() = default;
  // Any thread. The link's callbacks run on `worker`; `who` names the plugin instance in logs. May throw.
  virtual std::unique_ptr<sdk::R2rLink> make_link(sdk::Worker& worker, std::string who) = 0;
};

}  // namespace rcand::kernel
