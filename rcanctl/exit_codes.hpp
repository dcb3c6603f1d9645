// rcanctl's exit codes, the same for every subcommand (scripts test them).
#pragma once

namespace rcand::rcanctl {

inline constexpr int kExitOk = 0;       // everything asked for was done
inline constexpr int kExitFailure = 1;  // a robot refused, failed or did not answer (fleet commands: at least one)
inline constexpr int kExitUsage = 2;    // a bad command line or config; nothing was sent

}  // namespace rcand::rcanctl
