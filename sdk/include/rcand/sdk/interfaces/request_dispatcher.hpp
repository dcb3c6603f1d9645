// Requests on behalf of a caller (a service, rcand/sdk/services.hpp; offered by rcand itself). A plugin that turns
// something else into robot commands - the chat capability turning an instruction into an action - hands the command
// to rcand as the HTTP request it stands for, from the principal who asked, with that caller's credential. It then runs
// exactly as that HTTP request would at that moment: the caller authorized again, the same route table, the scope
// check for what the credential grants now, the audit entry, the 423 e-stop pre-check, and the capability's handler.
// A plugin therefore never reaches another plugin's driver, and has no way around the motion gate - or past a revoked
// credential - that an HTTP client would not also have.
//
// Not for a capability's own routes from its own handler: its requests run one at a time on its worker, so a handler
// waiting for a request to itself would wait for its own turn.
#pragma once

#include <cstddef>
#include <functional>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE RequestDispatcher {
 public:
  // /3 (ABI 1.3): the caller is authorized again at each dispatch, from Request::credential. /2 ran a request with its
  // role's default scopes and is no longer offered: a plugin built for it finds no dispatcher (its documented null).
  static constexpr std::string_view kServiceId = "rcand.request_dispatcher/3";
  // The largest audit note rcand records (its JSON text, in bytes).
  static constexpr std::size_t kAuditNoteLimit = 2048;
  virtual ~RequestDispatcher() = default;
  // Runs `request` as an HTTP request from the caller whose `request.credential` it carries - the credential of the
  // request the plugin acts for, copied from it - authorized again now, exactly as that caller's own HTTP request
  // would be: a credential no longer accepted (a pre-shared token removed by a config reload, a JWT past its exp) is
  // refused 401 UNAUTHORIZED, one whose scopes (a role lowered, a JWT's scope claim) do not cover the route 403
  // INSUFFICIENT_PRIVILEGES, and the principal and role are the credential's (request.principal and request.role are
  // not trusted). No credential (null, or one rcand did not make): 401 UNAUTHORIZED, nothing runs. method, path,
  // query and body are used; `message_id` (empty: one is made) names it in the audit log. `done` is called exactly
  // once, from any thread (possibly before dispatch returns), with the answer the HTTP client would have got. Any
  // thread, never blocks.
  //
  // `audit_note`: what the dispatching plugin adds to the request's audit entry, so the entry says why it happened
  // (the chat capability: {"ai": {"provider", "model", "confidence", "inference_latency_ms", "thought_id"}}). null
  // for none, else an object whose keys are lowercase names ([a-z][a-z0-9_]{0,31}) other than the entry's own
  // fields (seq, principal, ruri, message_id, event, timestamp_ms, outcome, detail, kind), at most kAuditNoteLimit
  // bytes as JSON. A note that breaks these rules is a bug in the plugin: the request is not run and `done` gets
  // 500 INVALID_AUDIT_NOTE.
  virtual void dispatch(Request request, Json audit_note, std::function<void(Response)> done) const noexcept = 0;
};

}  // namespace rcand::sdk
