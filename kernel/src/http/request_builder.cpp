#include "request_builder.hpp"

#include <string_view>

#include "target.hpp"

namespace rcand::kernel::http::detail {

namespace {

// Boost 1.74's Beast speaks boost::string_view.
std::string_view ssv(boost::beast::string_view s) noexcept { return {s.data(), s.size()}; }

std::string ascii_case(std::string_view text, char from, char to) {
  std::string out{text};
  for (char& c : out)
    if (c >= from && c <= static_cast<char>(from + 25)) c = static_cast<char>(c - from + to);
  return out;
}

}  // namespace

void configure_parser(RequestParser& parser, std::size_t body_limit) {
  parser.header_limit(kHeaderLimit);
  parser.body_limit(static_cast<std::uint64_t>(body_limit));
  parser.eager(true);
}

std::string build_request(RequestParser::value_type& message, std::string remote, Request& out) {
  out.method = ascii_case(ssv(message.method_string()), 'a', 'A');
  out.target = std::string{ssv(message.target())};
  if (auto problem = parse_target(out.target, out.path, out.query); !problem.empty()) return problem;
  for (const auto& field : message) {
    auto [it, inserted] = out.headers.try_emplace(ascii_case(ssv(field.name_string()), 'A', 'a'), ssv(field.value()));
    if (!inserted) {
      it->second += ", ";
      it->second.append(ssv(field.value()));
    }
  }
  out.body = std::move(message.body());
  out.remote = std::move(remote);
  return {};
}

}  // namespace rcand::kernel::http::detail
