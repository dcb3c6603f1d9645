#include "kernel/api/router.hpp"

#include <algorithm>
#include <stdexcept>

#include <rcand/sdk/contract/route_match.hpp>

namespace rcand::kernel {
namespace {

sdk::contract::RowKey route_row_key(const Route& r) { return {r.spec.method, r.spec.path, {}}; }

void add_route_row(std::vector<Route>& rows, Route row) {
  for (const auto& route : rows)
    if (route.spec.method == row.spec.method && route.spec.path == row.spec.path)
      throw std::logic_error("route " + row.spec.method + " " + row.spec.path + " added twice");
  rows.push_back(std::move(row));
}

}  // namespace

Router::Router() : table_(std::make_shared<const RouteTable>()) {}

void Router::add(RouteSpec spec, RouteHandler handler, std::string group) {
  std::lock_guard lock(writers_);
  add_route_row(rows_, {std::move(spec), std::move(handler), {}, std::move(group)});
  publish();
}

void Router::replace_group(const std::string& group, std::vector<std::pair<RouteSpec, RouteHandler>> rows) {
  std::vector<std::function<void()>> listeners;
  {
    std::lock_guard lock(writers_);
    std::vector<Route> next;
    for (const auto& route : rows_)
      if (route.group != group) next.push_back(route);
    for (auto& [spec, handler] : rows) add_route_row(next, {std::move(spec), std::move(handler), {}, group});
    rows_ = std::move(next);
    publish();
    listeners = group_listeners_;
  }
  for (const auto& listener : listeners) listener();
}

void Router::on_group_replaced(std::function<void()> listener) {
  std::lock_guard lock(writers_);
  group_listeners_.push_back(std::move(listener));
}

void Router::wrap(std::string_view method, std::string_view path, Decorator decorator) {
  std::lock_guard lock(writers_);
  Wrapping wrapping{std::string(method), std::string(path), std::move(decorator)};
  auto current = table_.load()->routes;
  apply(current, wrapping);  // the row must exist now
  wrappings_.push_back(std::move(wrapping));
  table_.store(std::make_shared<const RouteTable>(RouteTable{std::move(current)}));
}

void Router::apply(std::vector<Route>& routes, const Wrapping& wrapping) const {
  const Route* found = sdk::contract::match_rows(routes, route_row_key, wrapping.method, wrapping.path).row;
  if (found == nullptr) throw std::logic_error("no route " + wrapping.method + " " + wrapping.path + " to wrap");
  Route& route = routes[static_cast<std::size_t>(found - routes.data())];
  Decorator inner = route.decorator
                        ? std::move(route.decorator)
                        : Decorator([](Call& call, Reply reply, const RouteHandler& next) { next(call, std::move(reply)); });
  route.decorator = [method = wrapping.method, outer = wrapping.decorator, inner = std::move(inner)](Call& call, Reply reply,
                                                                                                     const RouteHandler& next) {
    const RouteHandler rest = [&inner, &next](Call& c, Reply r) { inner(c, std::move(r), next); };
    if (call.request.method == method) outer(call, std::move(reply), rest);
    else rest(call, std::move(reply));
  };
}

// The rows, each wrapping applied in the order they were made (a row a later group replaced keeps its path's ones).
void Router::publish() {
  std::vector<Route> routes = rows_;
  for (const auto& wrapping : wrappings_) {
    if (sdk::contract::match_rows(routes, route_row_key, wrapping.method, wrapping.path).row == nullptr) continue;
    apply(routes, wrapping);
  }
  table_.store(std::make_shared<const RouteTable>(RouteTable{std::move(routes)}));
}

Router::Match Router::match(std::string_view method, std::string_view path) const {
  // The contract's matching (rcand/sdk/contract/route_match.hpp), as the fake host's.
  auto table = table_.load();
  auto found = sdk::contract::match_rows(table->routes, route_row_key, method, path);
  return {std::move(table), found.row, std::move(found.allowed)};
}

}  // namespace rcand::kernel
