#include "libs/http/request.hpp"

namespace rcand::http {

std::optional<std::string_view> Request::header(std::string_view lower_name) const {
  auto it = headers.find(std::string{lower_name});
  if (it == headers.end()) return std::nullopt;
  return std::string_view{it->second};
}

std::string client_address(std::string_view remote) {
  if (!remote.empty() && remote.front() == '[') return std::string(remote.substr(1, remote.find(']') - 1));
  return std::string(remote.substr(0, remote.rfind(':')));
}

}  // namespace rcand::http
