// Robots with their own addresses (header-only): network namespaces on a bridge, as
// /work/shared/recipes/swarm-namespaces.sh does. Needs root and the `ip` tool; available() says whether this
// machine allows it (tests then fall back to loopback and say so; RCAND_TEST_NO_NETNS=1 forces the fallback). Everything created is removed by the destructor.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace rcand::test {

class NetnsLab {
 public:
  // `count` namespaces, each with one address 10.203.<k>.<i> on a bridge that the root namespace reaches (.254).
  explicit NetnsLab(int count) {
    for (const char* candidate : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"})
      if (std::filesystem::exists(candidate)) ip_ = candidate;
    const std::string id = std::to_string(::getpid() % 100000);
    bridge_ = "brsw" + id;
    subnet_ = "10.203." + std::to_string(::getpid() % 250) + ".";
    if (std::getenv("RCAND_TEST_NO_NETNS") != nullptr) {
      why_ = "disabled by RCAND_TEST_NO_NETNS";
      return;
    }
    if (ip_.empty() || ::geteuid() != 0) {
      why_ = ip_.empty() ? "no 'ip' tool" : "not root";
      return;
    }
    if (!run("link add " + bridge_ + " type bridge") || !run("addr add " + subnet_ + "254/24 dev " + bridge_) ||
        !run("link set " + bridge_ + " up")) {
      why_ = "cannot create a bridge (no CAP_NET_ADMIN?)";
      return;
    }
    bridge_made_ = true;
    for (int i = 1; i <= count; ++i) {
      const std::string ns = "rcsw" + id + "-" + std::to_string(i);
      const std::string veth = "vsw" + id + "x" + std::to_string(i);
      if (!run("netns add " + ns)) {
        why_ = "cannot create a network namespace";
        return;
      }
      namespaces_.push_back(ns);
      if (!run("link add " + veth + " type veth peer name eth0 netns " + ns) || !run("link set " + veth + " master " + bridge_ + " up") ||
          !run("-n " + ns + " addr add " + address(i) + "/24 dev eth0") || !run("-n " + ns + " link set lo up") ||
          !run("-n " + ns + " link set eth0 up")) {
        why_ = "cannot wire namespace " + ns;
        return;
      }
    }
    ok_ = true;
  }
  ~NetnsLab() {
    for (const auto& ns : namespaces_) run("netns del " + ns);  // also removes its end of the veth pair
    if (bridge_made_) run("link del " + bridge_);
  }
  NetnsLab(const NetnsLab&) = delete;
  NetnsLab& operator=(const NetnsLab&) = delete;

  bool available() const { return ok_; }
  const std::string& why_not() const { return why_; }
  // The i-th robot's (1-based) address and launcher.
  std::string address(int i) const { return subnet_ + std::to_string(i); }
  std::vector<std::string> launcher(int i) const { return {ip_, "netns", "exec", namespaces_.at(static_cast<std::size_t>(i - 1))}; }

 private:
  bool run(const std::string& args) const { return std::system((ip_ + " " + args + " >/dev/null 2>&1").c_str()) == 0; }

  std::string ip_, bridge_, subnet_, why_;
  std::vector<std::string> namespaces_;
  bool bridge_made_ = false, ok_ = false;
};

}  // namespace rcand::test
