#include "kernel/api/request_dispatch.hpp"

#include "kernel/auth/caller_credential.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/logging.hpp"

#include <algorithm>
#include <array>
#include <cctype>

namespace rcand::kernel {
namespace {

// Why `note` breaks sdk::RequestDispatcher's rules for an audit note, or empty when it keeps them.
std::string audit_note_fault(const nlohmann::json& note) {
  if (note.is_null()) return {};
  if (!note.is_object()) return "the audit note is not an object";
  static constexpr std::array kEntryFields{"seq",          "principal", "ruri",   "message_id", "event",
                                           "timestamp_ms", "outcome",   "detail", "kind"};
  for (const auto& [key, value] : note.items()) {
    const bool named = !key.empty() && key.size() <= 32 && std::islower(static_cast<unsigned char>(key[0])) &&
                       key.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_") == std::string::npos;
    if (!named) return "audit note key '" + bounded_text(key, 40) + "' is not a lowercase name";
    if (std::find(kEntryFields.begin(), kEntryFields.end(), key) != kEntryFields.end())
      return "audit note key '" + key + "' is one of the entry's own fields";
  }
  const auto size = note.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace).size();
  if (size > sdk::RequestDispatcher::kAuditNoteLimit)
    return "audit note of " + std::to_string(size) + " bytes (limit " + std::to_string(sdk::RequestDispatcher::kAuditNoteLimit) +
           ")";
  return {};
}

}  // namespace

void KernelRequestDispatcher::dispatch(sdk::Request request, sdk::Json audit_note,
                                       std::function<void(sdk::Response)> done) const noexcept {
  try {
    if (const auto fault = audit_note_fault(audit_note); !fault.empty()) {
      logger("kernel.api")
          ->error("a plugin's request {} {} was not run: {}", bounded_text(request.method, 16), bounded_text(request.path, 200),
                  fault);
      done(sdk::Response::error(500, "INVALID_AUDIT_NOTE", "request not dispatched: " + fault));
      return;
    }
    // The caller is authorized again, now, from the credential its own request came with: never from the principal
    // and role the plugin names (a HiTL approval may come long after the caller's token was revoked).
    const auto* caller = dynamic_cast<const CallerCredential*>(request.credential.get());
    if (caller == nullptr) {
      logger("kernel.api")
          ->error("a plugin's request {} {} was not run: it carries no caller credential", bounded_text(request.method, 16),
                  bounded_text(request.path, 200));
      done(sdk::Response::error(401, "UNAUTHORIZED",
                                "request not dispatched: it carries no caller credential (Request::credential of the "
                                "request it acts for)"));
      return;
    }
    http::Request http;
    http.method = std::move(request.method);
    http.target = http.path = std::move(request.path);
    http.query = std::move(request.query);
    http.query.erase("token");  // the caller's credential, and nothing else, authorizes it
    if (!request.body.is_null()) http.body = request.body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    http.remote = "plugin";
    if (caller->bearer()) http.headers["authorization"] = "Bearer " + *caller->bearer();
    if (!request.message_id.empty()) http.headers["x-message-id"] = std::move(request.message_id);
    api_.execute_for_caller(
        std::move(http),
        [done](http::Response response) {
          // A stream or a binary body (a snapshot JPEG) has no JSON to hand back: the caller learns what it was.
          if (response.stream != nullptr || response.content_type != "application/json") {
            done(sdk::Response{response.status, {{"content_type", response.content_type}, {"bytes", response.body.size()}}});
            return;
          }
          auto body = nlohmann::json::parse(response.body, nullptr, false);
          done(sdk::Response{response.status, body.is_discarded() ? nlohmann::json::object() : std::move(body)});
        },
        std::move(audit_note));
  } catch (const std::exception& e) {  // no memory: the request never ran
    done(sdk::Response::error(500, "INTERNAL", std::string("request not dispatched: ") + e.what()));
  }
}

}  // namespace rcand::kernel
