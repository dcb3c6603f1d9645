#include "libs/http/request_builder.hpp"

#include <algorithm>
#include <string_view>

#include "libs/base/bounded_text.hpp"
#include "libs/http/target.hpp"

namespace rcand::http::detail {

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

std::optional<HeaderRefusal> check_header(const RequestParser::value_type& message) {
  const auto method = ssv(message.method_string());
  if (std::any_of(method.begin(), method.end(), [](char c) { return c >= 'a' && c <= 'z'; }))
    return HeaderRefusal{400, "BAD_REQUEST",
                         "method '" + bounded_text(method, 32) + "' is not upper case (HTTP methods are case-sensitive)"};
  if (message.version() >= 11 && message.find(boost::beast::http::field::host) == message.end())
    return HeaderRefusal{400, "BAD_REQUEST", "an HTTP/1.1 request needs a Host header"};
  if (const auto coding = message.find(boost::beast::http::field::transfer_encoding); coding != message.end()) {
    std::string codings;
    for (const auto& field : message)
      if (field.name() == boost::beast::http::field::transfer_encoding)
        codings += (codings.empty() ? "" : ",") + std::string(ssv(field.value()));
    std::erase_if(codings, [](char c) { return c == ' ' || c == '\t'; });
    if (ascii_case(codings, 'A', 'a') != "chunked")
      return HeaderRefusal{501, "NOT_IMPLEMENTED",
                           "Transfer-Encoding '" + bounded_text(codings, 64) + "' is not supported: only chunked alone is"};
  }
  return std::nullopt;
}

void configure_parser(RequestParser& parser, std::size_t body_limit) {
  parser.header_limit(kHeaderLimit);
  parser.body_limit(static_cast<std::uint64_t>(body_limit));
  parser.eager(true);
}

std::string build_request(RequestParser::value_type& message, std::string remote, Request& out) {
  out.method = std::string{ssv(message.method_string())};  // upper case already (check_header)
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

}  // namespace rcand::http::detail
