#include "libs/http/request.hpp"

namespace rcand::http {

std::optional<std::string_view> Request::header(std::string_view lower_name) const {
  auto it = headers.find(std::string{lower_name});
  if (it == headers.end()) return std::nullopt;
  return std::string_view{it->second};
}

}  // namespace rcand::http
