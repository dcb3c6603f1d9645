// `rcanctl token ...`: issue HS256 JWTs and make pre-shared tokens for runtime.auth.tokens[] (docs/protocol.md §3).
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace rcand::rcanctl {

// `args` are the words after "token". Exit codes: 0 ok, 2 usage or input error (message on `err`), 1 internal error.
int run_token(std::span<const std::string> args, std::istream& in, std::ostream& out, std::ostream& err);
// The same on std::cin, std::cout and std::cerr: the subcommand table's entry point.
int run_token(std::span<const std::string> args);

}  // namespace rcand::rcanctl
