// The operators' R2R endpoints (README "R2R"): GET /api/r2r/peers (status), POST /api/r2r/send (control: send one
// message as this robot), POST /api/r2r/auction (control: run an auction here, answered when decided), GET
// /api/r2r/auction/<task_id> (status). 404 R2R_DISABLED when runtime.r2r.enabled is off.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "libs/http/handler.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::kernel {

struct ApiContext;

inline constexpr std::string_view kR2rRoutePrefix = "/api/r2r/";

// The scope a route needs; nullopt for no such route (handle_r2r_route then answers 404 or 405 unauthenticated).
std::optional<sdk::Scope> r2r_route_scope(std::string_view method, std::string_view path);

// Runs an authorized /api/r2r/ request. Audits POSTs as `principal` under `message_id`. Never blocks.
void handle_r2r_route(ApiContext& context, const http::Request& request, const std::string& principal,
                      const std::string& message_id, http::Respond respond);

}  // namespace rcand::kernel
