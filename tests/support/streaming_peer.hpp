// A swarm peer that answers every connection with an endless body (a declared 1 GB), written as fast as the socket
// takes it: the "streaming peer" of issue 13 #4. For the fan-out's unit test and the broadcast-stop benchmark.
#pragma once

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/write.hpp>

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

namespace rcand::test {

class StreamingPeer {
 public:
  StreamingPeer() {
    acceptor_thread_ = std::thread([this] {
      while (!stopping_) {
        boost::system::error_code ec;
        boost::asio::ip::tcp::socket socket(io_);
        acceptor_.accept(socket, ec);
        if (ec || stopping_) return;
        writers_.emplace_back([this, socket = std::move(socket)]() mutable {
          boost::system::error_code write_ec;
          const std::string head =
              "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: 1000000000\r\n\r\n{\"p\":\"";
          boost::asio::write(socket, boost::asio::buffer(head), write_ec);
          const std::string chunk(64 * 1024, 'x');
          while (!write_ec && !stopping_) boost::asio::write(socket, boost::asio::buffer(chunk), write_ec);
        });
      }
    });
  }
  ~StreamingPeer() {
    stopping_ = true;
    boost::system::error_code ec;
    boost::asio::ip::tcp::socket poke(io_);
    poke.connect(acceptor_.local_endpoint(), ec);  // wakes the blocking accept
    acceptor_thread_.join();
    for (auto& writer : writers_) writer.join();
  }
  StreamingPeer(const StreamingPeer&) = delete;
  StreamingPeer& operator=(const StreamingPeer&) = delete;
  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_{io_, {boost::asio::ip::make_address("127.0.0.1"), 0}};
  std::atomic<bool> stopping_{false};
  std::vector<std::thread> writers_;  // only the acceptor thread adds, before the destructor joins it
  std::thread acceptor_thread_;
};

}  // namespace rcand::test
