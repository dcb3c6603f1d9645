// The route table: every HTTP endpoint rcand serves is one row (method, path, scope, audited, motion) and one named
// handler. Rows are added at startup (kernel routes, the capabilities' rows, each service's routes); a group of rows
// (the capabilities') is replaced while serving as each capability comes up. The table is an immutable snapshot,
// swapped whole: matching loads it atomically and takes no lock, and a request keeps the snapshot it matched in for
// as long as it runs. The middleware that runs before every handler (message id, rate limits, authentication, the
// audit entry, the e-stop pre-check) lives in Api, once.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>
#include <rcand/sdk/scope.hpp>

#include "libs/http/handler.hpp"

namespace rcand::kernel {

// One request as the middleware hands it to a handler: authenticated, rate-limited, and (for an audited row)
// recorded in the audit log as pending under `audit_seq`.
struct Call {
  http::Request request;
  std::string principal = "anonymous";
  sdk::Role role = sdk::Role::Guest;
  std::string message_id;
  std::vector<sdk::Scope> scopes;  // what the principal's credential grants
  bool peer = false;               // authenticated by its transport (an R2R node), not by a credential of its own
  std::uint64_t audit_seq = 0;     // 0: this row is not audited by the middleware
  nlohmann::json audit_note;       // what a plugin's RequestDispatcher call adds to the audit entry (AuditEntry::note)

  bool has_scope(sdk::Scope scope) const {
    return scope == sdk::Scope::None || std::find(scopes.begin(), scopes.end(), scope) != scopes.end();
  }
};

// Answers the request (the middleware adds X-Message-Id); call exactly once, from any thread.
using Reply = std::function<void(http::Response)>;
using RouteHandler = std::function<void(Call&, Reply)>;

struct RouteSpec {
  std::string method;  // "GET", "POST", or "*" for any method
  // An exact path ("/api/estop"), or a prefix ending in '*' ("/api/drivers/*"): exact rows win, then the
  // longest prefix.
  std::string path;
  sdk::Scope scope = sdk::Scope::Status;
  bool audited = false;      // the middleware records "METHOD path" (pending) before the handler; the handler
                             // finishes it (Call::audit_seq) with its outcome
  bool motion = false;       // 423 ESTOP_ACTIVE while latched, before the handler
  bool rate_limited = true;  // false only for the e-stop paths (docs/protocol.md §6.4)
  bool stop = false;         // an audited stop: kept in the stops' retention, a repeat while latched coalesced into
                             // the entry it repeats (AuditLog::begin_stop; Call::audit_seq is then 0)
};

using Decorator = std::function<void(Call&, Reply, const RouteHandler& next)>;

struct Route {
  RouteSpec spec;
  RouteHandler handler;
  Decorator decorator;  // empty: none
  std::string group;    // replace_group()'s key; empty: a row for good
};

// One snapshot of the table: never changed once published.
struct RouteTable {
  std::vector<Route> routes;
};

class Router {
 public:
  Router();
  // A second row with the same method and path is a programming error (std::logic_error). Writers (add, wrap,
  // replace_group) are serialized; each publishes a new snapshot.
  void add(RouteSpec spec, RouteHandler handler, std::string group = {});
  // Any thread: every row of `group` replaced by `rows` in one swap (a row that clashes with another group's is a
  // std::logic_error, and nothing changes). The wraps made so far apply to the new rows as to the old.
  void replace_group(const std::string& group, std::vector<std::pair<RouteSpec, RouteHandler>> rows);
  // `decorator` runs for `method` requests the row at `path` serves, after authentication and
  // before the audit entry and the e-stop pre-check; `next` runs those and the row's handler. A service extends an
  // endpoint this way (the swarm broadcast wraps POST /api/stop: its own audit entry, then the local stop through
  // `next`, then the fan-out). The row must exist.
  void wrap(std::string_view method, std::string_view path, Decorator decorator);
  // Any thread: `listener` runs after each replace_group(), outside the writers' lock (it may wrap the new rows).
  void on_group_replaced(std::function<void()> listener);

  struct Match {
    std::shared_ptr<const RouteTable> table;  // holds `route` alive while the request runs
    const Route* route = nullptr;             // null: no row for this method
    std::vector<std::string> allowed;         // the methods the path has, when route is null (empty: 404)
  };
  // Any thread, no lock: one atomic load of the current snapshot.
  Match match(std::string_view method, std::string_view path) const;
  std::shared_ptr<const RouteTable> routes() const { return table_.load(); }

 private:
  struct Wrapping {
    std::string method, path;
    Decorator decorator;
  };
  void apply(std::vector<Route>& routes, const Wrapping& wrapping) const;  // throws when no row serves it
  void publish();                                                          // under writers_

  std::mutex writers_;
  std::vector<Route> rows_;  // every row undecorated; under writers_
  std::vector<Wrapping> wrappings_;
  std::vector<std::function<void()>> group_listeners_;  // under writers_
  std::atomic<std::shared_ptr<const RouteTable>> table_;
};

}  // namespace rcand::kernel
