// Text without its leading and trailing whitespace: how chat reads an instruction and a model server's answer.
#pragma once

#include <string>

namespace rcand::plugins::chat {

inline std::string trimmed(const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return {};
  return text.substr(first, text.find_last_not_of(" \t\r\n") - first + 1);
}

}  // namespace rcand::plugins::chat
