#include "services/telemetry/metrics_text.hpp"

#include <charconv>
#include <cmath>

namespace rcand::services::telemetry {

std::string escape_label_value(std::string_view value) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    if (c == '\\') out += "\\\\";
    else if (c == '"') out += "\\\"";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

std::string escape_help(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '\\') out += "\\\\";
    else if (c == '\n') out += "\\n";
    else out += c;
  }
  return out;
}

std::string format_value(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  char buffer[32];
  // Whole numbers (counts, most gauges) print as integers; everything else as the shortest exact decimal.
  if (value == std::trunc(value) && std::fabs(value) < 1e15) {
    const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, static_cast<long long>(value));
    return std::string(buffer, ec == std::errc() ? end : buffer);
  }
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, ec == std::errc() ? end : buffer);
}

void MetricsText::family(std::string_view name, std::string_view type, std::string_view help) {
  name_ = std::string(name);
  names_.push_back(name_);
  out_ += "# HELP " + name_ + " " + escape_help(help) + "\n";
  out_ += "# TYPE " + name_ + " " + std::string(type) + "\n";
}

void MetricsText::line(std::string_view suffix, const Labels& labels, const std::pair<std::string, std::string>* extra,
                       double value) {
  out_ += name_;
  out_ += suffix;
  if (!labels.empty() || extra != nullptr) {
    out_ += '{';
    bool first = true;
    auto add = [&](const std::pair<std::string, std::string>& label) {
      if (!first) out_ += ',';
      first = false;
      out_ += label.first + "=\"" + escape_label_value(label.second) + "\"";
    };
    for (const auto& label : labels) add(label);
    if (extra != nullptr) add(*extra);
    out_ += '}';
  }
  out_ += ' ';
  out_ += format_value(value);
  out_ += '\n';
}

void MetricsText::sample(const Labels& labels, double value) { line("", labels, nullptr, value); }

void MetricsText::histogram(const Labels& labels, const HistogramSample& h) {
  for (std::size_t i = 0; i < h.bounds.size() && i < h.cumulative.size(); ++i) {
    const std::pair<std::string, std::string> le{"le", format_value(h.bounds[i])};
    line("_bucket", labels, &le, static_cast<double>(h.cumulative[i]));
  }
  const std::pair<std::string, std::string> inf{"le", "+Inf"};
  line("_bucket", labels, &inf, static_cast<double>(h.count));
  line("_sum", labels, nullptr, h.sum);
  line("_count", labels, nullptr, static_cast<double>(h.count));
}

}  // namespace rcand::services::telemetry
