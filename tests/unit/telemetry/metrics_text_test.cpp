// The Prometheus text writer and the lock-free histogram: the exact lines, escaping, and (where Debian's
// prometheus package is installed) `promtool check metrics` with no finding on a page of every kind of family.
#include <doctest/doctest.h>

#include <iostream>

#include "promtool.hpp"
#include "services/telemetry/latency_histogram.hpp"
#include "services/telemetry/metrics_text.hpp"
#include "services/telemetry/status_metrics.hpp"

using namespace rcand::services::telemetry;
using namespace std::chrono_literals;

TEST_CASE("metrics text: values, label and help escaping") {
  CHECK(format_value(3) == "3");
  CHECK(format_value(0.25) == "0.25");
  CHECK(format_value(1.0 / 0.0) == "+Inf");
  CHECK(format_value(0.0 / 0.0) == "NaN");
  CHECK(escape_label_value("a\"b\\c\nd") == "a\\\"b\\\\c\\nd");
  CHECK(escape_help("x\\y\nz") == "x\\\\y\\nz");

  MetricsText out;
  out.family("rcand_things_total", "counter", "things\ncounted");
  out.sample({{"kind", "a\"b"}}, 2);
  out.sample(5);
  CHECK(out.text() ==
        "# HELP rcand_things_total things\\ncounted\n# TYPE rcand_things_total counter\n"
        "rcand_things_total{kind=\"a\\\"b\"} 2\nrcand_things_total 5\n");
}

TEST_CASE("latency histogram: cumulative buckets, +Inf, sum in seconds") {
  static constexpr std::array<double, 3> bounds{0.001, 0.01, 0.1};
  LatencyHistogram h(bounds);
  h.observe(500us);   // <= 0.001
  h.observe(1ms);     // == 0.001: le is inclusive
  h.observe(50ms);    // <= 0.1
  h.observe(2000ms);  // +Inf only
  const auto sample = h.read();
  REQUIRE(sample.cumulative.size() == 3);
  CHECK(sample.cumulative[0] == 2);
  CHECK(sample.cumulative[1] == 2);
  CHECK(sample.cumulative[2] == 3);
  CHECK(sample.count == 4);
  CHECK(sample.sum == doctest::Approx(2.0515));

  MetricsText out;
  out.family("rcand_x_seconds", "histogram", "x");
  out.histogram({{"route", "/a"}}, sample);
  CHECK(out.text().find("rcand_x_seconds_bucket{route=\"/a\",le=\"0.001\"} 2\n") != std::string::npos);
  CHECK(out.text().find("rcand_x_seconds_bucket{route=\"/a\",le=\"+Inf\"} 4\n") != std::string::npos);
  CHECK(out.text().find("rcand_x_seconds_count{route=\"/a\"} 4\n") != std::string::npos);
}

TEST_CASE("status metrics: states one-hot, plugins, nav; promtool finds nothing") {
  const nlohmann::json status = {
      {"ruri", "rcan://acme/bot/1"},
      {"name", "bot \"one\""},
      {"version", "0.9"},
      {"rcan_version", "1.3.0"},
      {"state", "estop"},
      {"estopped", true},
      {"uptime_s", 12},
      {"nav_running", false},
      {"plugins", {{{"id", "org.rcand.sim_drive"}, {"state", "loaded"}}}},
      {"capabilities",
       {{"teleop", {{"state", "ok"}}}, {"nav", {{"state", "ok"}, {"stale", true}}}, {"vision", {{"state", "failed"}}}}},
      {"drivers", {{{"id", "drive0"}, {"state", "ok"}}}}};
  MetricsText out;
  write_status_metrics(out, status);
  static constexpr std::array<double, 2> bounds{0.001, 0.01};
  LatencyHistogram h(bounds);
  h.observe(2ms);
  out.family("rcand_http_request_duration_seconds", "histogram", "per route");
  out.histogram({{"method", "GET"}, {"route", "/api/status"}}, h.read());
  const std::string& text = out.text();
  CHECK(text.find("rcand_estop_latched 1\n") != std::string::npos);
  CHECK(text.find("rcand_robot_state{state=\"estop\"} 1\n") != std::string::npos);
  CHECK(text.find("rcand_robot_state{state=\"idle\"} 0\n") != std::string::npos);
  CHECK(text.find("rcand_capability_state{capability=\"nav\",state=\"stale\"} 1\n") != std::string::npos);
  CHECK(text.find("rcand_capability_state{capability=\"vision\",state=\"failed\"} 1\n") != std::string::npos);
  CHECK(text.find("rcand_driver_state{driver=\"drive0\",state=\"ok\"} 1\n") != std::string::npos);
  CHECK(text.find("name=\"bot \\\"one\\\"\"") != std::string::npos);

  rcand::test::check_promtool_clean(text);
}
