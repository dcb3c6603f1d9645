#include "libs/http/target.hpp"

namespace rcand::http::detail {

namespace {

int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool iequals_ascii(std::string_view a, std::string_view b) noexcept {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    char x = a[i] >= 'A' && a[i] <= 'Z' ? static_cast<char>(a[i] - 'A' + 'a') : a[i];
    if (x != b[i]) return false;
  }
  return true;
}

// Decoded text must not smuggle a NUL into file names or C APIs further down.
std::optional<std::string> decode_component(std::string_view text, bool plus_is_space) {
  auto decoded = percent_decode(text, plus_is_space);
  if (decoded && decoded->find('\0') != std::string::npos) return std::nullopt;
  return decoded;
}

}  // namespace

std::optional<std::string> percent_decode(std::string_view text, bool plus_is_space) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    char c = text[i];
    if (c == '%') {
      if (i + 2 >= text.size()) return std::nullopt;  // truncated escape
      int hi = hex_value(text[i + 1]);
      int lo = hex_value(text[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      out.push_back(static_cast<char>(hi * 16 + lo));
      i += 2;
    } else if (c == '+' && plus_is_space) {
      out.push_back(' ');
    } else {
      out.push_back(c);
    }
  }
  return out;
}

std::string parse_target(std::string_view target, std::string& path, std::map<std::string, std::string>& query) {
  path.clear();
  query.clear();
  if (target == "*") {  // OPTIONS * HTTP/1.1
    path = "*";
    return {};
  }
  std::string_view rest = target;
  std::string absolute_rest;  // owns "/" + remainder when an absolute-form target has no path
  if (rest.empty() || rest.front() != '/') {
    auto scheme_end = rest.find("://");
    if (scheme_end == std::string_view::npos ||
        !(iequals_ascii(rest.substr(0, scheme_end), "http") || iequals_ascii(rest.substr(0, scheme_end), "https"))) {
      return "the request target must start with '/'";
    }
    auto after_authority = rest.substr(scheme_end + 3);
    auto pos = after_authority.find_first_of("/?#");
    rest = pos == std::string_view::npos ? std::string_view{} : after_authority.substr(pos);
    if (rest.empty() || rest.front() != '/') {
      absolute_rest = "/";
      absolute_rest.append(rest);
      rest = absolute_rest;
    }
  }
  if (auto hash = rest.find('#'); hash != std::string_view::npos) rest = rest.substr(0, hash);

  auto question = rest.find('?');
  auto raw_path = rest.substr(0, question);
  auto decoded_path = decode_component(raw_path, false);
  if (!decoded_path) return "bad percent-encoding in the request path";
  path = std::move(*decoded_path);
  if (question == std::string_view::npos) return {};

  std::string_view raw_query = rest.substr(question + 1);
  while (!raw_query.empty()) {
    auto amp = raw_query.find('&');
    auto pair = raw_query.substr(0, amp);
    raw_query = amp == std::string_view::npos ? std::string_view{} : raw_query.substr(amp + 1);
    if (pair.empty()) continue;
    auto eq = pair.find('=');
    auto key = decode_component(pair.substr(0, eq), true);
    auto value =
        eq == std::string_view::npos ? std::optional<std::string>{std::string{}} : decode_component(pair.substr(eq + 1), true);
    if (!key || !value) {
      query.clear();
      return "bad percent-encoding in the query string";
    }
    query.try_emplace(std::move(*key), std::move(*value));
  }
  return {};
}

}  // namespace rcand::http::detail
