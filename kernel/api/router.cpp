#include "kernel/api/router.hpp"

#include <algorithm>
#include <stdexcept>

#include <rcand/sdk/contract/route_match.hpp>

namespace rcand::kernel {

void Router::add(RouteSpec spec, RouteHandler handler) {
  for (const auto& route : routes_)
    if (route.spec.method == spec.method && route.spec.path == spec.path)
      throw std::logic_error("route " + spec.method + " " + spec.path + " added twice");
  routes_.push_back({std::move(spec), std::move(handler), {}});
}

void Router::wrap(std::string_view method, std::string_view path, Decorator decorator) {
  const Route* found = match(method, path).route;
  if (found == nullptr) throw std::logic_error("no route " + std::string(method) + " " + std::string(path) + " to wrap");
  Route& route = routes_[static_cast<std::size_t>(found - routes_.data())];
  Decorator inner = route.decorator
                        ? std::move(route.decorator)
                        : Decorator([](Call& call, Reply reply, const RouteHandler& next) { next(call, std::move(reply)); });
  route.decorator = [method = std::string(method), outer = std::move(decorator), inner = std::move(inner)](
                        Call& call, Reply reply, const RouteHandler& next) {
    const RouteHandler rest = [&inner, &next](Call& c, Reply r) { inner(c, std::move(r), next); };
    if (call.request.method == method) outer(call, std::move(reply), rest);
    else rest(call, std::move(reply));
  };
}

Router::Match Router::match(std::string_view method, std::string_view path) const {
  // The contract's matching (rcand/sdk/contract/route_match.hpp), as the fake host's.
  auto found = sdk::contract::match_rows(
      routes_,
      [](const Route& r) {
        return sdk::contract::RowKey{r.spec.method, r.spec.path, {}};
      },
      method, path);
  return {found.row, std::move(found.allowed)};
}

}  // namespace rcand::kernel
