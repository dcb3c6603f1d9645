// A real mosquitto broker for tests (header-only): listens on 127.0.0.1 on a free port with a config of its own in a
// temporary directory, anonymous or with a password file (and an acl_file); ready when its port accepts connections (polled, no
// fixed sleep); stopped with SIGTERM (SIGKILL if it lingers) and reaped. restart() keeps the port, for reconnect tests.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <pwd.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace rcand::test {

inline std::uint16_t free_tcp_port() {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor acceptor(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  return acceptor.local_endpoint().port();
}

inline bool tcp_port_open(std::uint16_t port) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket socket(io);
  boost::system::error_code ec;
  socket.connect({boost::asio::ip::make_address("127.0.0.1"), port}, ec);
  return !ec;
}

struct BrokerUser {
  std::string name, password;
};

class MosquittoBroker {
 public:
  // user/password empty: anonymous clients allowed; otherwise only that user (password file made with mosquitto_passwd).
  explicit MosquittoBroker(std::string user = {}, std::string password = {})
      : MosquittoBroker(user.empty() ? std::vector<BrokerUser>{} : std::vector<BrokerUser>{{user, password}}, {}) {}
  // Only these users (password_file made with mosquitto_passwd -b), each held to acl_file when one is given.
  MosquittoBroker(std::vector<BrokerUser> users, std::filesystem::path acl_file)
      : users_(std::move(users)), acl_file_(std::move(acl_file)) {
    std::random_device random;
    dir_ = std::filesystem::temp_directory_path() / ("rcand-mqtt-" + std::to_string(::getpid()) + "-" + std::to_string(random()));
    std::filesystem::create_directories(dir_);
    port_ = free_tcp_port();
    try {
      configure();
      start();
    } catch (...) {
      std::error_code ec;
      std::filesystem::remove_all(dir_, ec);
      throw;
    }
  }
  ~MosquittoBroker() {
    stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  MosquittoBroker(const MosquittoBroker&) = delete;
  MosquittoBroker& operator=(const MosquittoBroker&) = delete;

  void configure() {
    std::ofstream conf(dir_ / "mosquitto.conf");
    // Started as root, mosquitto would switch to the `mosquitto` user and lose access to our files: stay who we are.
    if (const passwd* me = ::getpwuid(::geteuid())) conf << "user " << me->pw_name << "\n";
    conf << "listener " << port_ << " 127.0.0.1\n"
         << "persistence false\nset_tcp_nodelay true\nlog_dest stderr\nlog_type error\nlog_type warning\n";
    if (users_.empty()) {
      conf << "allow_anonymous true\n";
    } else {
      conf << "allow_anonymous false\npassword_file " << (dir_ / "passwd").string() << "\n";
      for (std::size_t i = 0; i < users_.size(); ++i) {
        const std::string command = "mosquitto_passwd -b " + std::string(i == 0 ? "-c " : "") + "'" + (dir_ / "passwd").string() +
                                    "' '" + users_[i].name + "' '" + users_[i].password + "' >/dev/null 2>&1";
        if (std::system(command.c_str()) != 0) throw std::runtime_error("mosquitto_passwd failed");
      }
      std::filesystem::permissions(dir_ / "passwd", std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    }
    // As docs/examples/mosquitto-acl.conf says: the client id is the username, so no one takes over another's session.
    if (!acl_file_.empty()) conf << "acl_file " << acl_file_.string() << "\nuse_username_as_clientid true\n";
    conf.close();
  }

  std::uint16_t port() const noexcept { return port_; }
  const std::filesystem::path& dir() const noexcept { return dir_; }

  void start() {
    if (pid_ > 0) return;
    std::cout.flush();  // the child must not write the parent's buffered output again
    std::fflush(nullptr);
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      const std::string conf = (dir_ / "mosquitto.conf").string();
      const std::string log = (dir_ / "broker.log").string();
      if (FILE* out = std::freopen(log.c_str(), "a", stderr); out == nullptr) _exit(126);
      ::execlp("mosquitto", "mosquitto", "-c", conf.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!tcp_port_open(port_)) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("mosquitto exited at start; see " + (dir_ / "broker.log").string());
      }
      if (std::chrono::steady_clock::now() > deadline) throw std::runtime_error("mosquitto did not start listening");
      std::this_thread::sleep_for(std::chrono::milliseconds(10));  // polling the port: there is no event to wait on
    }
  }

  // SIGKILL (a broker that dies: no clean goodbye to its clients) and reap.
  void kill_hard() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid_ = -1;
  }

 private:
  std::filesystem::path dir_;
  std::vector<BrokerUser> users_;
  std::filesystem::path acl_file_;
  std::uint16_t port_ = 0;
  pid_t pid_ = -1;
};

}  // namespace rcand::test
