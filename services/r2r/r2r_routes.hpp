// The operators' R2R endpoints (README "R2R"): GET /api/r2r/peers (status), POST /api/r2r/send (control: send one
// message as this robot), POST /api/r2r/auction (control: run an auction here, answered when decided), GET
// /api/r2r/auction/<task_id> (status). 404 R2R_DISABLED when runtime.r2r.enabled is off. The two auction rows are
// answered by the fleet plugin (sdk::FleetAuctions, found at each request): 503 UNAVAILABLE naming org.rcand.fleet
// when it is not running.
#pragma once

#include "kernel/api/router.hpp"
#include "kernel/audit/audit_log.hpp"

namespace rcand::services::r2r {

class R2rService;

// Startup. `service` null: R2R is off (every row answers R2R_DISABLED). Both outlive the router's use of them.
void add_r2r_routes(kernel::Router& router, R2rService* service, kernel::AuditLog& audit);

}  // namespace rcand::services::r2r
