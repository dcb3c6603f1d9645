// mDNS test lab: robots on a LAN of their own, each in a network namespace (NetnsLab) with a private system
// D-Bus and its own avahi-daemon, as /work/shared/recipes/mdns-two-namespaces.sh does. Daemons can be killed and
// restarted; the destructor stops every process it started and removes the namespaces and files (the tmpfs that
// keeps the daemons' pid files apart lives in each daemon's private mount namespace and goes with it).
// available() is false (with why_not()) where the machine cannot do this: tests then skip and say so.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "netns_lab.hpp"
#include "rcand_process.hpp"

namespace rcand::test {

class AvahiLab {
 public:
  explicit AvahiLab(int count);
  ~AvahiLab();
  AvahiLab(const AvahiLab&) = delete;
  AvahiLab& operator=(const AvahiLab&) = delete;

  bool available() const { return ok_; }
  const std::string& why_not() const { return why_; }

  std::string address(int i) const { return net_.address(i); }
  // The avahi host name of namespace i (append ".local" for its mDNS name).
  std::string host_name(int i) const;
  std::string bus_address(int i) const;
  // Runs a command inside namespace i, talking to that namespace's avahi-daemon: {ip netns exec NS env DBUS=...}.
  std::vector<std::string> launcher(int i) const;

  // SIGKILL (a crash, no goodbyes) and reap. start_daemon waits for "Server startup complete".
  void kill_daemon(int i);
  bool start_daemon(int i);

  // A tool run to completion inside namespace i.
  ProcessResult run(int i, const std::string& binary, const std::vector<std::string>& args) const;

  // One `avahi-browse -rpt TYPE` from namespace i: resolved instances by name (unescaped), each as its TXT map
  // plus "@address" and "@port".
  std::map<std::string, std::map<std::string, std::string>> browse(int i, const std::string& type = "_rcan._tcp") const;

 private:
  struct Node {
    pid_t dbus = -1, avahi = -1;
    int dbus_stdout = -1;
  };
  bool start_bus(int i);
  std::string dir(int i) const;

  NetnsLab net_;
  TempDir temp_;
  std::vector<Node> nodes_;
  std::string id_, why_;
  bool ok_ = false;
};

}  // namespace rcand::test
