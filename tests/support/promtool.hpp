// `promtool check metrics` (Debian's prometheus package) on a metrics text: its findings, or why it could not run.
// Shared by the unit tests and the integration test; a test without promtool skips saying so.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>

#include <unistd.h>

#include <doctest/doctest.h>

#include <iostream>

namespace rcand::test {

inline bool have_promtool() { return std::system("command -v promtool >/dev/null 2>&1") == 0; }

// Exit status and output of `promtool check metrics` reading `text` on stdin; nullopt when promtool is absent.
struct PromtoolResult {
  int exit_code = -1;
  std::string output;
};
inline std::optional<PromtoolResult> promtool_check(const std::string& text) {
  if (!have_promtool()) return std::nullopt;
  char path[] = "/tmp/rcand-metrics-XXXXXX";
  const int fd = ::mkstemp(path);
  if (fd < 0) return PromtoolResult{-1, "mkstemp failed"};
  ::close(fd);
  std::ofstream(path) << text;
  const std::string command = std::string("promtool check metrics < ") + path + " 2>&1";
  PromtoolResult result;
  if (FILE* pipe = ::popen(command.c_str(), "r")) {
    char buffer[4096];
    while (std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) result.output.append(buffer, n);
    const int status = ::pclose(pipe);
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::remove(path);
  return result;
}

// The check every metrics test makes: promtool finds nothing in `text` (skipped, saying so, without promtool).
inline void check_promtool_clean(const std::string& text) {
  const auto checked = promtool_check(text);
  if (!checked) {
    std::cerr << "promtool not installed (apt-get install --no-install-recommends prometheus): metrics lint skipped\n";
    return;
  }
  INFO(checked->output, "\n", text);
  CHECK(checked->exit_code == 0);
  CHECK(checked->output.empty());
}

}  // namespace rcand::test
