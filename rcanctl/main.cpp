// rcanctl: the command-line client of rcand. Each subcommand lives in its own file; add one with one table row.
#include <algorithm>
#include <iostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "discover_command.hpp"
#include "doctor_command.hpp"
#include "exit_codes.hpp"
#include "fleet_command.hpp"
#include "operator_commands.hpp"
#include "r2r_command.hpp"
#include "robot_commands.hpp"
#include "swarm_command.hpp"
#include "token_command.hpp"
#include "watch_command.hpp"

namespace {

struct Subcommand {
  std::string_view name;
  std::string_view summary;
  int (*run)(std::span<const std::string> args);  // the words after the name; returns the exit code
};

constexpr Subcommand kSubcommands[] = {
    {"token", "issue JWTs (token issue), hash or create pre-shared tokens (token hash, token new)", rcand::rcanctl::run_token},
    {"status", "one robot's status, and each failed driver or capability with why and the fix (or --node NAME)",
     rcand::rcanctl::run_status},
    {"stop", "latch one robot's e-stop and confirm its motors stopped", rcand::rcanctl::run_stop},
    {"command", "send one robot an instruction (--instruction \"...\"); prints what it understood and did",
     rcand::rcanctl::run_command},
    {"estop", "show the e-stop (estop), or clear it (estop clear, owner token)", rcand::rcanctl::run_estop},
    {"move", "teleop: move --linear X --angular Y [--duration MS | --hold]", rcand::rcanctl::run_move},
    {"nav", "nav go --distance M [--heading DEG] [--speed S] | nav status | nav cancel", rcand::rcanctl::run_nav},
    {"plugins", "every plugin and its driver/capability instances: state, health, why one failed; plugins reload ID",
     rcand::rcanctl::run_plugins},
    {"audit", "the audit log, oldest first (--limit N, --follow; owner token)", rcand::rcanctl::run_audit},
    {"doctor", "what is wrong with this robot's setup, and the command that fixes each", rcand::rcanctl::run_doctor},
    {"swarm", "status|stop|command on swarm.yaml nodes in parallel (--node, --tag, --swarm, --json)", rcand::rcanctl::run_swarm},
    {"discover", "find robots on the LAN by mDNS (_rcan._tcp) and check each one's DISCOVER document (--timeout S, --json)",
     rcand::rcanctl::run_discover},
    {"fleet", "a fleet's R2R keys (keygen, enroll, revoke, list) and its e-stop over MQTT (fleet stop --mqtt)",
     rcand::rcanctl::run_fleet},
    {"r2r", "robot-to-robot: send one message and print the answers, watch traffic, run an auction (r2r --help)",
     rcand::rcanctl::run_r2r},
    {"watch", "live telemetry (WS /ws/telemetry): a refreshing table, or JSON lines with --json", rcand::rcanctl::run_watch},
};

void print_usage(std::ostream& out) {
  out << "usage: rcanctl <subcommand> [args...]\n\nsubcommands:\n";
  for (const Subcommand& sub : kSubcommands) {
    const std::size_t pad = sub.name.size() < 12 ? 12 - sub.name.size() : 1;
    out << "  " << sub.name << std::string(pad, ' ') << sub.summary << "\n";
  }
  out << "\nrcanctl <subcommand> --help lists all its options (man rcanctl: every subcommand).\n";
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + (argc > 0 ? 1 : 0), argv + argc);
  if (args.empty()) {
    print_usage(std::cerr);
    return rcand::rcanctl::kExitUsage;
  }
  if (args.front() == "--help" || args.front() == "-h" || args.front() == "help") {
    print_usage(std::cout);
    return rcand::rcanctl::kExitOk;
  }
  for (const Subcommand& sub : kSubcommands)
    if (args.front() == sub.name) {
      try {
        return sub.run(std::span<const std::string>(args).subspan(1));
      } catch (const std::exception& e) {
        std::cerr << "rcanctl " << sub.name << ": " << e.what() << "\n";
        return rcand::rcanctl::kExitFailure;
      }
    }
  std::cerr << "rcanctl: unknown subcommand '" << args.front() << "'\n\n";
  print_usage(std::cerr);
  return rcand::rcanctl::kExitUsage;
}
