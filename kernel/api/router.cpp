#include "kernel/api/router.hpp"

#include <algorithm>
#include <stdexcept>

namespace rcand::kernel {
namespace {

bool is_prefix(const std::string& path) { return !path.empty() && path.back() == '*'; }

// 0: no match; otherwise larger is more specific (an exact row beats every prefix, a longer prefix a shorter one).
std::size_t specificity(const std::string& pattern, std::string_view path) {
  if (!is_prefix(pattern)) return pattern == path ? std::string::npos : 0;
  const std::string_view prefix(pattern.data(), pattern.size() - 1);
  return path.size() > prefix.size() && path.substr(0, prefix.size()) == prefix ? prefix.size() : 0;
}

}  // namespace

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
  // The most specific pattern with a row for this method (or "*") wins: POST on a path whose exact row is GET-only
  // falls through to a prefix row, so a capability's mount answers it (after authentication) rather than the table.
  Match found;
  std::size_t found_specificity = 0, top = 0;
  int found_rank = 0;
  for (const auto& route : routes_) {
    const std::size_t s = specificity(route.spec.path, path);
    if (s == 0) continue;
    top = std::max(top, s);
    const int rank = route.spec.method == method ? 2 : route.spec.method == "*" ? 1 : 0;
    if (rank > 0 && (s > found_specificity || (s == found_specificity && rank > found_rank))) {
      found.route = &route;
      found_specificity = s;
      found_rank = rank;
    }
  }
  if (found.route != nullptr) return found;
  for (const auto& route : routes_)
    if (top != 0 && specificity(route.spec.path, path) == top) found.allowed.push_back(route.spec.method);
  return found;
}

}  // namespace rcand::kernel
