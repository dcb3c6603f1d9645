#include <doctest/doctest.h>

#include "libs/yaml/config_diff.hpp"

using namespace rcand;
using nlohmann::json;

TEST_CASE("changed_keys names the leaf paths that differ; lists count as one value") {
  const json before{{"runtime", {{"logging", {{"level", "info"}}}, {"auth", {{"tokens", json::array({1, 2})}}}}},
                    {"drivers", json::array({{{"id", "a"}}})},
                    {"metadata", {{"robot_name", "r"}}}};
  json after = before;
  CHECK(changed_keys(before, after).empty());
  after["runtime"]["logging"]["level"] = "warn";
  after["runtime"]["auth"]["tokens"].push_back(3);
  after["drivers"][0]["id"] = "b";
  after["metadata"].erase("robot_name");
  after["safety"] = {{"watchdog_ms", 100}};
  CHECK(changed_keys(before, after) ==
        std::vector<std::string>{"drivers", "metadata.robot_name", "runtime.auth.tokens", "runtime.logging.level", "safety"});
}

TEST_CASE("key_is_under matches whole path segments only") {
  CHECK(key_is_under("runtime.auth.tokens", "runtime.auth"));
  CHECK(key_is_under("runtime.auth", "runtime.auth"));
  CHECK_FALSE(key_is_under("runtime.authority", "runtime.auth"));
  CHECK_FALSE(key_is_under("runtime", "runtime.auth"));
}
