// The Prometheus text exposition format (version 0.0.4), written by hand: rcand's counters are its own atomics,
// read once per scrape, so a client library's registry and threads would add nothing. Each family is written
// whole (HELP, TYPE, then its samples) so `promtool check metrics` finds them grouped as it requires.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rcand::services::telemetry {

using Labels = std::vector<std::pair<std::string, std::string>>;

// Cumulative bucket counts of one histogram as read for a scrape: counts[i] observations <= bounds[i], then the
// +Inf count (== count), the sum in the family's base unit.
struct HistogramSample {
  std::span<const double> bounds;
  std::vector<std::uint64_t> cumulative;  // bounds.size() entries
  std::uint64_t count = 0;
  double sum = 0.0;
};

class MetricsText {
 public:
  // Starts a family. `type`: "counter", "gauge" or "histogram". A counter's name ends in "_total".
  void family(std::string_view name, std::string_view type, std::string_view help);
  // A sample of the current (counter or gauge) family.
  void sample(const Labels& labels, double value);
  void sample(double value) { sample({}, value); }
  // The _bucket, _sum and _count samples of the current (histogram) family.
  void histogram(const Labels& labels, const HistogramSample& h);

  const std::string& text() const noexcept { return out_; }
  // The families started so far, in order.
  const std::vector<std::string>& family_names() const noexcept { return names_; }
  static constexpr std::string_view kContentType = "text/plain; version=0.0.4; charset=utf-8";

 private:
  void line(std::string_view suffix, const Labels& labels, const std::pair<std::string, std::string>* extra, double value);
  std::string name_;
  std::string out_;
  std::vector<std::string> names_;
};

// A label value or HELP text escaped as the format requires (backslash, double quote in label values, newline).
std::string escape_label_value(std::string_view value);
std::string escape_help(std::string_view text);
// A sample value: integers without a fraction, "+Inf", "-Inf", "NaN", else the shortest round-trip decimal.
std::string format_value(double value);

}  // namespace rcand::services::telemetry
