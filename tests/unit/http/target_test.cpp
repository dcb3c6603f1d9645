#include <doctest/doctest.h>

#include "target.hpp"

using rcand::http::detail::parse_target;
using rcand::http::detail::percent_decode;

TEST_CASE("percent_decode decodes escapes and optionally '+'") {
  CHECK(percent_decode("a%20b%2Fc", false) == "a b/c");
  CHECK(percent_decode("a+b", false) == "a+b");
  CHECK(percent_decode("a+b", true) == "a b");
  CHECK(percent_decode("%e2%82%AC", false) == "\xe2\x82\xac");
  CHECK_FALSE(percent_decode("%", false).has_value());
  CHECK_FALSE(percent_decode("abc%2", false).has_value());
  CHECK_FALSE(percent_decode("%zz", false).has_value());
}

TEST_CASE("parse_target splits the path and the query") {
  std::string path;
  std::map<std::string, std::string> query;
  CHECK(parse_target("/a%20b/c?x=1&y=hello+world&x=2&flag&&z=%26", path, query).empty());
  CHECK(path == "/a b/c");
  CHECK(query == std::map<std::string, std::string>{{"x", "1"}, {"y", "hello world"}, {"flag", ""}, {"z", "&"}});

  CHECK(parse_target("/p+q#frag", path, query).empty());
  CHECK(path == "/p+q");
  CHECK(query.empty());

  CHECK(parse_target("http://robot.local:8000/api/status?a=b", path, query).empty());
  CHECK(path == "/api/status");
  CHECK(query.at("a") == "b");
  CHECK(parse_target("HTTP://robot.local?a=b", path, query).empty());
  CHECK(path == "/");
  CHECK(query.at("a") == "b");

  CHECK(parse_target("*", path, query).empty());
  CHECK(path == "*");
}

TEST_CASE("parse_target refuses bad targets with a reason") {
  std::string path;
  std::map<std::string, std::string> query;
  CHECK(parse_target("relative/path", path, query) == "the request target must start with '/'");
  CHECK(parse_target("ftp://host/x", path, query) == "the request target must start with '/'");
  CHECK(parse_target("/a%zz", path, query) == "bad percent-encoding in the request path");
  CHECK(parse_target("/a%00b", path, query) == "bad percent-encoding in the request path");
  CHECK(parse_target("/a?token=%zz", path, query) == "bad percent-encoding in the query string");
  CHECK(query.empty());
}
