// Metrics contributed through sdk::Metrics (rcand/sdk/interfaces/metrics.hpp): the naming rules (shared by rcand and the fake
// host), refusals that never reach the page, many threads recording at once, and the exposition of every family
// type, checked by `promtool check metrics` where Debian's prometheus package is installed.
#include <doctest/doctest.h>

#include <rcand/sdk/contract/metric_rules.hpp>
#include <rcand/sdk/testing/recording_metrics.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <thread>
#include <vector>

#include "promtool.hpp"
#include "services/telemetry/plugin_metrics.hpp"

namespace sdk = rcand::sdk;
using rcand::services::telemetry::MetricsText;
using rcand::services::telemetry::PluginMetrics;
using sdk::MetricFamily;
using sdk::MetricType;

namespace {

constexpr std::array<std::string_view, 2> kAcmeCallLabels{"provider", "outcome"};
constexpr MetricFamily kAcmeCalls{"acme_brain_calls_total", MetricType::Counter, "brain calls by outcome", kAcmeCallLabels};
constexpr MetricFamily kAcmeViewers{"acme_stream_viewers", MetricType::Gauge, "viewers now", {}};
constexpr std::array<double, 3> kAcmeBounds{0.01, 0.1, 1};
constexpr std::array<std::string_view, 1> kAcmeProviderLabel{"provider"};
constexpr MetricFamily kAcmeLatency{"acme_brain_call_duration_seconds", MetricType::Histogram, "call latency", kAcmeProviderLabel,
                                    kAcmeBounds};

std::string acme_family_error(std::string_view name, MetricType type, std::span<const std::string_view> labels = {},
                              std::span<const double> buckets = {}) {
  return sdk::contract::metric_family_error(MetricFamily{name, type, "help", labels, buckets});
}

}  // namespace

TEST_CASE("metric rules: Prometheus naming conventions, labels and buckets") {
  CHECK(acme_family_error("acme_grabs_total", MetricType::Counter).empty());
  CHECK(acme_family_error("acme_queue_depth", MetricType::Gauge).empty());
  CHECK(acme_family_error("acme_call_duration_seconds", MetricType::Histogram).empty());
  CHECK(acme_family_error("acme_grabs", MetricType::Counter).find("must end in '_total'") != std::string::npos);
  CHECK(acme_family_error("acme_depth_total", MetricType::Gauge).find("only a counter") != std::string::npos);
  CHECK(acme_family_error("acme_latency_ms", MetricType::Gauge).find("abbreviated unit 'ms'") != std::string::npos);
  CHECK(acme_family_error("acme_latency_milliseconds", MetricType::Gauge).find("use seconds") != std::string::npos);
  CHECK(acme_family_error("acme_size_kilobytes", MetricType::Gauge).find("use bytes") != std::string::npos);
  CHECK(acme_family_error("acmeCalls_total", MetricType::Counter).find("snake_case") != std::string::npos);
  CHECK(acme_family_error("acme-calls_total", MetricType::Counter).find("snake_case") != std::string::npos);
  CHECK(acme_family_error("__acme_total", MetricType::Counter).find("snake_case") != std::string::npos);
  CHECK(acme_family_error("acme_gauge_value", MetricType::Gauge).find("type 'gauge'") != std::string::npos);
  CHECK(acme_family_error("acme_queue_count", MetricType::Gauge).find("'_count'") != std::string::npos);
  CHECK(acme_family_error("", MetricType::Gauge).find("snake_case") != std::string::npos);

  constexpr std::array<std::string_view, 1> le{"le"};
  constexpr std::array<std::string_view, 2> twice{"a", "a"};
  constexpr std::array<std::string_view, 1> upper{"Camera"};
  CHECK(acme_family_error("acme_x_total", MetricType::Counter, le).find("reserved") != std::string::npos);
  CHECK(acme_family_error("acme_x_total", MetricType::Counter, twice).find("given twice") != std::string::npos);
  CHECK(acme_family_error("acme_x_total", MetricType::Counter, upper).find("snake_case") != std::string::npos);

  constexpr std::array<double, 2> descending{1, 0.5};
  CHECK(acme_family_error("acme_x_seconds", MetricType::Histogram, {}, descending).find("increasing") != std::string::npos);
  CHECK(acme_family_error("acme_x_seconds", MetricType::Gauge, {}, kAcmeBounds).find("only a histogram") != std::string::npos);
  CHECK(sdk::contract::metric_family_error(MetricFamily{"acme_x_total", MetricType::Counter, "", {}, {}}).find("help") !=
        std::string::npos);

  // Label values are free text made safe for the page: invalid UTF-8 and control characters become '?', 128 bytes.
  CHECK(sdk::contract::metric_label_value("caf\xc3\xa9") == "caf\xc3\xa9");
  CHECK(sdk::contract::metric_label_value("a\xff\nb") == "a??b");
  CHECK(sdk::contract::metric_label_value(std::string(300, 'x')).size() == 128);
}

TEST_CASE("plugin metrics: refused calls return false, are counted and never reach the page") {
  PluginMetrics metrics({"rcand_http_requests_total"});
  const sdk::Metrics& api = metrics;
  CHECK(api.add(kAcmeCalls, {"grammar", "answered"}));
  CHECK_FALSE(api.add(kAcmeCalls, {"grammar"}));                            // one value for two labels
  CHECK_FALSE(api.add(kAcmeCalls, {"grammar", "answered"}, -1));            // a counter never goes down
  CHECK_FALSE(api.set(kAcmeCalls, {"grammar", "answered"}, 3));             // a counter only adds
  CHECK_FALSE(api.add(kAcmeCalls, {"grammar", "answered"}, std::nan("")));  // not a number
  constexpr MetricFamily as_gauge{"acme_brain_calls_total", MetricType::Gauge, "x", kAcmeCallLabels};
  CHECK_FALSE(api.set(as_gauge, {"a", "b"}, 1));  // the same name with another shape
  constexpr MetricFamily rcands_own{"rcand_http_requests_total", MetricType::Counter, "x", {}};
  CHECK_FALSE(api.add(rcands_own));
  constexpr MetricFamily bad_name{"acme_latency_ms", MetricType::Gauge, "x", {}};
  CHECK_FALSE(api.set(bad_name, 1));
  CHECK(metrics.refused() == 7);

  MetricsText out;
  metrics.write(out);
  CHECK(out.text() ==
        "# HELP acme_brain_calls_total brain calls by outcome\n# TYPE acme_brain_calls_total counter\n"
        "acme_brain_calls_total{provider=\"grammar\",outcome=\"answered\"} 1\n");
}

TEST_CASE("plugin metrics: too many label sets in one family are refused, the others kept") {
  PluginMetrics metrics({});
  const sdk::Metrics& api = metrics;
  for (std::size_t i = 0; i < sdk::contract::kMaxSeriesPerFamily; ++i)
    REQUIRE(api.add(kAcmeCalls, {"p" + std::to_string(i), "x"}));
  CHECK_FALSE(api.add(kAcmeCalls, {"one-more", "x"}));
  CHECK(api.add(kAcmeCalls, {"p0", "x"}));  // an existing set still counts
}

TEST_CASE("plugin metrics: threads recording at once lose nothing") {
  PluginMetrics metrics({});
  const sdk::Metrics& api = metrics;
  constexpr int kThreads = 8, kEach = 5000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&api, t] {
      for (int i = 0; i < kEach; ++i) {
        api.add(kAcmeCalls, {"p", t % 2 == 0 ? "answered" : "error"});
        api.observe(kAcmeLatency, {"p"}, 0.05);
        api.add(kAcmeViewers, {}, 1);
      }
    });
  for (int i = 0; i < 20; ++i) {  // a scrape racing the writers is whole too: each family once
    MetricsText racing;
    metrics.write(racing);
    CHECK(std::count(racing.family_names().begin(), racing.family_names().end(), "acme_stream_viewers") <= 1);
  }
  for (auto& thread : threads) thread.join();
  MetricsText out;
  metrics.write(out);
  const std::string& text = out.text();
  const int half = kThreads / 2 * kEach;
  CHECK(text.find("acme_brain_calls_total{provider=\"p\",outcome=\"answered\"} " + std::to_string(half) + "\n") !=
        std::string::npos);
  CHECK(text.find("acme_brain_calls_total{provider=\"p\",outcome=\"error\"} " + std::to_string(half) + "\n") !=
        std::string::npos);
  CHECK(text.find("acme_brain_call_duration_seconds_count{provider=\"p\"} " + std::to_string(kThreads * kEach) + "\n") !=
        std::string::npos);
  CHECK(text.find("acme_stream_viewers " + std::to_string(kThreads * kEach) + "\n") != std::string::npos);
  CHECK(metrics.refused() == 0);
}

TEST_CASE("plugin metrics: every family type whole, declared families before any sample; promtool finds nothing") {
  PluginMetrics metrics({});
  const sdk::Metrics& api = metrics;
  CHECK(api.declare(kAcmeCalls));  // shows (HELP and TYPE) before anything happened
  CHECK(api.set(kAcmeViewers, 2));
  CHECK(api.add(kAcmeViewers, {}, -1));
  CHECK(api.observe(kAcmeLatency, {"grammar"}, 0.0078125));
  CHECK(api.observe(kAcmeLatency, {"grammar"}, 0.5));
  CHECK(api.observe(kAcmeLatency, {"grammar"}, 7));         // +Inf only
  CHECK(api.observe(kAcmeLatency, {"say \"hi\"\\"}, 0.2));  // escaped on the page
  MetricsText out;
  metrics.write(out);
  const std::string& text = out.text();
  CHECK(text.find("# TYPE acme_brain_calls_total counter\n# HELP acme_stream_viewers") != std::string::npos);
  CHECK(text.find("acme_stream_viewers 1\n") != std::string::npos);
  CHECK(text.find("acme_brain_call_duration_seconds_bucket{provider=\"grammar\",le=\"0.01\"} 1\n"
                  "acme_brain_call_duration_seconds_bucket{provider=\"grammar\",le=\"0.1\"} 1\n"
                  "acme_brain_call_duration_seconds_bucket{provider=\"grammar\",le=\"1\"} 2\n"
                  "acme_brain_call_duration_seconds_bucket{provider=\"grammar\",le=\"+Inf\"} 3\n"
                  "acme_brain_call_duration_seconds_sum{provider=\"grammar\"} 7.5078125\n"
                  "acme_brain_call_duration_seconds_count{provider=\"grammar\"} 3\n") != std::string::npos);
  CHECK(text.find("provider=\"say \\\"hi\\\"\\\\\"") != std::string::npos);
  rcand::test::check_promtool_clean(text);
}

TEST_CASE("the fake host's RecordingMetrics keeps what a plugin recorded and refuses what rcand refuses") {
  sdk::testing::RecordingMetrics metrics;
  const sdk::Metrics& api = metrics;
  CHECK(api.add(kAcmeCalls, {"grammar", "answered"}));
  CHECK(api.add(kAcmeCalls, {"grammar", "answered"}, 2));
  CHECK(api.observe(kAcmeLatency, {"grammar"}, 0.02));
  CHECK_FALSE(api.add(kAcmeCalls, {"grammar", "answered"}, -1));
  CHECK(metrics.value("acme_brain_calls_total", {"grammar", "answered"}) == 3);
  CHECK(metrics.observations("acme_brain_call_duration_seconds", {"grammar"}) == std::vector<double>{0.02});
  REQUIRE(metrics.refusals().size() == 1);
  CHECK(metrics.refusals()[0].find("never goes down") != std::string::npos);
}
