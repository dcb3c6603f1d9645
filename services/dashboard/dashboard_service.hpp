// The web dashboard (issue 18): the page at `/`, its files under /dashboard/, and GET /api/session (who the page's
// token belongs to, so it shows an owner's controls only to owners). The page itself is public and holds no data:
// everything it shows comes from the authenticated API and WS /ws/telemetry with the operator's token.
#pragma once

#include <memory>

#include "kernel/service.hpp"

namespace rcand::services {

std::unique_ptr<kernel::Service> make_dashboard(kernel::ServiceHost& host);

}  // namespace rcand::services
