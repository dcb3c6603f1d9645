// The one rule for log text (issue 28 #9): whatever a message holds, it is one line that starts with rcand's own
// prefix - no forged lines, no journald priority of its own, no terminal escapes, no unbounded length.
#include <doctest/doctest.h>

#include <spdlog/sinks/ostream_sink.h>

#include <sstream>
#include <string>
#include <vector>

#include "libs/base/log_text.hpp"
#include "libs/base/logging.hpp"

using namespace rcand;

namespace {

// What `message` becomes when logged at `level` by a logger "test" with rcand's formatter (journald's or not).
std::string log_text_formatted(const std::string& message, bool journal, spdlog::level::level_enum level = spdlog::level::info) {
  std::ostringstream out;
  auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out);
  spdlog::logger log("test", sink);
  log.set_formatter(make_log_formatter(journal));
  log.log(level, "r2r: unauthorized status from '{}' via mqtt", message);
  return out.str();
}

std::vector<std::string> log_text_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

}  // namespace

TEST_CASE("log text: a forged line in foreign text stays inside the one line it was logged in") {
  const std::string forged = "robot\nerror [kernel.estop] e-stop cleared by owner\r\n<3>rcand: fake critical\x1b[2K";
  for (const bool journal : {false, true}) {
    CAPTURE(journal);
    const auto lines = log_text_lines(log_text_formatted(forged, journal, spdlog::level::warn));
    REQUIRE(lines.size() == 1);
    const std::string& line = lines[0];
    if (journal) CHECK(line.rfind("<4>warning [test] r2r: unauthorized status from 'robot\\n", 0) == 0);  // rcand's prefix only
    else CHECK(line.find(" [test] r2r: unauthorized status from 'robot\\nerror [kernel.estop]") != std::string::npos);
    CHECK(line.find("\\r\\n<3>rcand: fake critical\\x1b[2K' via mqtt") != std::string::npos);
    CHECK(line.find('\x1b') == std::string::npos);
    CHECK(line.find('\r') == std::string::npos);
  }
}

TEST_CASE("log text: controls, C1, invalid UTF-8 and line/bidi separators are escaped; other text passes unchanged") {
  CHECK(log_text("plain text, 100% ASCII: {} [] <3>") == "plain text, 100% ASCII: {} [] <3>");
  CHECK(log_text("tab\there") == "tab\\there");
  CHECK(log_text(std::string("nul\0byte", 8)) == "nul\\x00byte");
  CHECK(log_text("del\x7f") == "del\\x7f");
  CHECK(log_text("c1 \xc2\x85 nel, \xc2\x9b csi") == "c1 \\u0085 nel, \\u009b csi");
  CHECK(log_text("raw \x9b byte, cut \xe2\x82") == "raw \\x9b byte, cut \\xe2\\x82");
  CHECK(log_text("overlong \xc0\xaf slash") == "overlong \\xc0\\xaf slash");
  CHECK(log_text("ls \xe2\x80\xa8 ps \xe2\x80\xa9 rlo \xe2\x80\xae") == "ls \\u2028 ps \\u2029 rlo \\u202e");
  CHECK(log_text("caf\xc3\xa9 \xe6\x97\xa5\xe6\x9c\xac \xf0\x9f\xa4\x96") ==
        "caf\xc3\xa9 \xe6\x97\xa5\xe6\x9c\xac \xf0\x9f\xa4\x96");
}

TEST_CASE("log text: a 200 KB reply becomes one bounded line that says how much was left out") {
  const std::string reply = "The answer is:\n" + std::string(200 * 1024, 'x');
  const std::string text = log_text(reply);
  CHECK(text.size() <= kMaxLogMessageBytes);
  CHECK(text.rfind("The answer is:\\nxxx", 0) == 0);
  CHECK(text.find("...[+") != std::string::npos);
  CHECK(text.ends_with(" bytes]"));
  // Never cut inside a character or an escape.
  const std::string wide = log_text(std::string(3000, '\n'));
  CHECK(wide.size() <= kMaxLogMessageBytes);
  CHECK(wide.substr(0, wide.find("...[+")).size() % 2 == 0);
  const auto lines = log_text_lines(log_text_formatted(reply, true));
  REQUIRE(lines.size() == 1);
  CHECK(lines[0].size() < kMaxLogMessageBytes + 100);
  // Plain text within the bound is untouched.
  const std::string fits(kMaxLogMessageBytes, 'y');
  CHECK(log_text(fits) == fits);
}
