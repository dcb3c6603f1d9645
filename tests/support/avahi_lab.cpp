#include "avahi_lab.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

extern char** environ;

namespace rcand::test {
namespace fs = std::filesystem;
namespace {

std::string find_tool(std::initializer_list<const char*> candidates) {
  for (const char* candidate : candidates)
    if (fs::exists(candidate)) return candidate;
  return {};
}

pid_t spawn(const std::vector<std::string>& argv, const fs::path& output, int* stdout_pipe = nullptr) {
  int out[2] = {-1, -1};
  if (stdout_pipe && pipe2(out, O_CLOEXEC) != 0) return -1;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  if (stdout_pipe) posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
  else posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, output.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  std::vector<char*> args;
  for (const auto& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv.front().c_str(), &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (stdout_pipe) {
    close(out[1]);
    if (rc == 0) *stdout_pipe = out[0];
    else close(out[0]);
  }
  return rc == 0 ? pid : -1;
}

void stop_process(pid_t& pid, int signal) {
  if (pid <= 0) return;
  kill(pid, signal);
  int status = 0;
  waitpid(pid, &status, 0);
  pid = -1;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// avahi-browse -p escapes names: "\032" is a space (decimal), "\." a dot.
std::string unescape(const std::string& text) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\\' && i + 3 < text.size() && std::isdigit(static_cast<unsigned char>(text[i + 1])) &&
        std::isdigit(static_cast<unsigned char>(text[i + 2])) && std::isdigit(static_cast<unsigned char>(text[i + 3]))) {
      out += static_cast<char>(std::stoi(text.substr(i + 1, 3)));
      i += 3;
    } else if (text[i] == '\\' && i + 1 < text.size()) {
      out += text[++i];
    } else {
      out += text[i];
    }
  }
  return out;
}

}  // namespace

AvahiLab::AvahiLab(int count) : net_(count), id_(std::to_string(::getpid() % 100000)) {
  if (!net_.available()) {
    why_ = net_.why_not();
    return;
  }
  for (const char* tool : {"avahi-daemon", "dbus-daemon", "avahi-browse"})
    if (find_tool({(std::string("/usr/sbin/") + tool).c_str(), (std::string("/usr/bin/") + tool).c_str()}).empty()) {
      why_ = std::string("no ") + tool + " (apt install avahi-daemon avahi-utils dbus)";
      return;
    }
  nodes_.resize(static_cast<std::size_t>(count));
  for (int i = 1; i <= count; ++i) {
    fs::create_directories(dir(i));
    std::ofstream(dir(i) + "/bus.conf") << R"(<!DOCTYPE busconfig PUBLIC "-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN"
 "http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd">
<busconfig>
  <type>system</type>
  <listen>unix:path=)" << dir(i) << R"(/system_bus_socket</listen>
  <auth>EXTERNAL</auth>
  <policy context="default">
    <allow user="*"/> <allow own="*"/> <allow send_type="method_call"/>
    <allow send_destination="*"/> <allow receive_sender="*"/>
  </policy>
</busconfig>
)";
    std::ofstream(dir(i) + "/avahi.conf") << "[server]\nhost-name=" << host_name(i)
                                          << "\ndomain-name=local\nuse-ipv4=yes\nuse-ipv6=no\nallow-interfaces=eth0\n"
                                             "enable-dbus=yes\n[wide-area]\nenable-wide-area=no\n"
                                             "[publish]\npublish-hinfo=no\npublish-workstation=no\n";
    if (!start_bus(i) || !start_daemon(i)) {
      why_ = "cannot start dbus-daemon/avahi-daemon in namespace " + std::to_string(i) + ": " +
             slurp(dir(i) + "/avahi.log") + slurp(dir(i) + "/dbus.log");
      return;
    }
  }
  ok_ = true;
}

AvahiLab::~AvahiLab() {
  for (auto& node : nodes_) {
    stop_process(node.avahi, SIGTERM);
    stop_process(node.dbus, SIGTERM);
    if (node.dbus_stdout >= 0) close(node.dbus_stdout);
  }
}  // then the TempDir and the namespaces go

std::string AvahiLab::dir(int i) const { return (temp_.path() / ("ns" + std::to_string(i))).string(); }
std::string AvahiLab::host_name(int i) const { return "rcm" + id_ + "n" + std::to_string(i); }
std::string AvahiLab::bus_address(int i) const { return "unix:path=" + dir(i) + "/system_bus_socket"; }

std::vector<std::string> AvahiLab::launcher(int i) const {
  auto command = net_.launcher(i);
  command.push_back("/usr/bin/env");
  command.push_back("DBUS_SYSTEM_BUS_ADDRESS=" + bus_address(i));
  return command;
}

bool AvahiLab::start_bus(int i) {
  auto& node = nodes_.at(static_cast<std::size_t>(i - 1));
  // --print-address: the bus is ready once it printed its address (an event on the pipe, no polling).
  node.dbus = spawn({find_tool({"/usr/bin/dbus-daemon", "/bin/dbus-daemon"}), "--config-file=" + dir(i) + "/bus.conf",
                     "--nofork", "--nopidfile", "--print-address=1"},
                    dir(i) + "/dbus.log", &node.dbus_stdout);
  if (node.dbus <= 0) return false;
  pollfd ready{node.dbus_stdout, POLLIN, 0};
  return poll(&ready, 1, 10000) == 1;
}

bool AvahiLab::start_daemon(int i) {
  auto& node = nodes_.at(static_cast<std::size_t>(i - 1));
  if (node.avahi > 0) return true;
  const std::string log = dir(i) + "/avahi.log";
  std::ofstream(log, std::ios::trunc).close();
  auto command = launcher(i);
  command.insert(command.end(), {"/bin/sh", "-c",
                                 "mkdir -p /run/avahi-daemon && mount -t tmpfs tmpfs /run/avahi-daemon && exec avahi-daemon -f " +
                                     dir(i) + "/avahi.conf --no-drop-root --no-chroot --no-rlimits"});
  node.avahi = spawn(command, log);
  if (node.avahi <= 0) return false;
  // avahi-daemon reports readiness only in its log: poll that condition, with a generous deadline.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < deadline) {
    if (slurp(log).find("Server startup complete") != std::string::npos) return true;
    if (waitpid(node.avahi, nullptr, WNOHANG) == node.avahi) {
      node.avahi = -1;
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

void AvahiLab::kill_daemon(int i) { stop_process(nodes_.at(static_cast<std::size_t>(i - 1)).avahi, SIGKILL); }

ProcessResult AvahiLab::run(int i, const std::string& binary, const std::vector<std::string>& args) const {
  auto command = launcher(i);
  command.push_back(binary);
  command.insert(command.end(), args.begin(), args.end());
  const std::string program = command.front();
  return run_tool(program, std::vector<std::string>(command.begin() + 1, command.end()));
}

std::map<std::string, std::map<std::string, std::string>> AvahiLab::browse(int i, const std::string& type) const {
  const auto result = run(i, find_tool({"/usr/bin/avahi-browse", "/bin/avahi-browse"}), {"-rpt", type});
  std::map<std::string, std::map<std::string, std::string>> found;
  std::istringstream lines(result.out);
  for (std::string line; std::getline(lines, line);) {
    // =;iface;proto;name;type;domain;host;address;port;"k=v" "k=v"...
    if (line.rfind("=;", 0) != 0) continue;
    std::vector<std::string> fields;
    std::size_t start = 0;
    for (int f = 0; f < 9; ++f) {
      const auto semicolon = line.find(';', start);
      fields.push_back(line.substr(start, semicolon - start));
      start = semicolon == std::string::npos ? line.size() : semicolon + 1;
    }
    auto& entry = found[unescape(fields[3])];
    entry["@address"] = fields[7];
    entry["@port"] = fields[8];
    const std::string txt = line.substr(start);
    for (std::size_t q = txt.find('"'); q != std::string::npos; q = txt.find('"', q)) {
      const auto end = txt.find('"', q + 1);
      if (end == std::string::npos) break;
      const std::string pair = txt.substr(q + 1, end - q - 1);
      const auto eq = pair.find('=');
      entry[pair.substr(0, eq)] = eq == std::string::npos ? "" : pair.substr(eq + 1);
      q = end + 1;
    }
  }
  return found;
}

}  // namespace rcand::test
