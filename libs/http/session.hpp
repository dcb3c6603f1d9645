// One HTTP connection: reads a request, hands it to the Handler, writes the answer, repeats while kept alive.
// Every member function runs on the owning slot's thread; only Responder crosses threads, by dispatching there.
//
// Placement: on the accept loop (ServerOptions::priority set) a new connection's requests are read there while they
// are priority requests, and handled there too; the first other request moves the connection (its socket, buffered
// bytes and that request) to a worker loop for good. A busy-lane connection answers one priority request, or 503.
//
// Streamed answers (Response::stream): the header goes out with "Connection: close" and no Content-Length, then each
// part the producer pushes, one write at a time; meanwhile a read watches for the client leaving. The connection
// closes when the stream ends, the client leaves, one part takes longer than stream_stall_timeout to write, or no part
// is offered for stream_stall_timeout.
//
// Screen: every request, upgrades included, is first offered to ServerOptions::screen (rcand: the browser-origin
// rule); an answer from it refuses the request before the upgrade hook and the Handler see it.
//
// WebSocket seam: an upgrade request is offered to ServerOptions::upgrade in dispatch_request(); when the hook takes
// it, the stream, the raw request and the buffered bytes move out (http/upgrade.hpp) and this object simply ends.
//
// TLS (a session made with a context; always on a worker loop): the handshake comes first, under header_timeout. A
// client that speaks plain HTTP there gets one plain 400 TLS_REQUIRED and the connection closes.
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "libs/http/busy_lane.hpp"
#include "libs/http/connection_stream.hpp"
#include "libs/http/connection_ticket.hpp"
#include "libs/http/request.hpp"
#include "libs/http/response.hpp"
#include "libs/http/response_stream.hpp"
#include "libs/http/server_core.hpp"

namespace rcand::http::detail {

using Stream = TcpStream;

class Session : public std::enable_shared_from_this<Session> {
 public:
  enum class Placement { Worker, AcceptLoop, BusyLane };
  // Holds `ticket` (its place in the limits) for its whole life, or hands it on when it moves to a worker.
  // `tls` set: a TLS connection (Placement::Worker only).
  Session(ServerCore& core, IoSlot& slot, Stream::socket_type socket, std::unique_ptr<ConnectionTicket> ticket,
          Placement placement, std::shared_ptr<boost::asio::ssl::context> tls = nullptr);
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  void start();
  void close() noexcept;
  // What the client has sent that is not yet handled, for the busy lane: what this session has read, and with
  // `look_in_socket` also what waits unread in the socket (a system call).
  PendingInput pending_input(bool look_in_socket) noexcept;
  // Answers the request in flight; ignored when closed or when nothing is in flight.
  void send(Response response);
  boost::asio::io_context::executor_type executor() const noexcept { return slot_.ioc.get_executor(); }
  ServerCore& core() const noexcept { return core_; }

 private:
  void handshake();
  // Plain HTTP sent to the TLS port: one plain answer saying so, then close.
  void refuse_plain_http();
  void wait_for_request();
  void new_parser();
  void parse_buffered();
  void read_header();
  void on_header(boost::beast::error_code ec);
  void read_body();
  void on_read_error(boost::beast::error_code ec);
  void dispatch_request();
  void handle(Request request);
  // From the accept loop to a worker loop, for good: there it handles `request`.
  void move_to_worker(Request request);
  void answer_busy();
  // ServerOptions::screen refused the request: its answer is on its way and the connection closes after it.
  bool refused_by_screen(const Request& request);
  // A WebSocket upgrade offered to ServerOptions::upgrade; false when the hook leaves it to the Handler.
  bool try_upgrade(Request& request);
  void send_error_and_close(int status, std::string_view code, std::string_view message);
  void write(Response response, bool close_after);
  void on_write(boost::beast::error_code ec, bool close_after);
  void linger_close();
  void drain();
  // A streamed answer, once its header is written: parts as they come, until the end or the client leaves.
  void start_streaming();
  void pump();
  void await_part();
  void watch_client();
  void end_stream();

  ServerCore& core_;
  IoSlot& slot_;
  std::unique_ptr<ConnectionTicket> ticket_;
  Placement placement_;
  ConnectionStream stream_;
  boost::beast::flat_buffer buffer_;
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;
  boost::beast::http::request<boost::beast::http::string_body> message_;    // the request being handled (parser's)
  boost::beast::http::response<boost::beast::http::string_body> response_;  // alive while being written
  std::string remote_;
  std::size_t drained_ = 0;
  unsigned version_ = 11;
  bool keep_alive_ = false;
  bool head_ = false;
  bool awaiting_response_ = false;
  bool fresh_ = true;  // no request read yet: the first one gets header_timeout from accept
  bool closed_ = false;
  bool raw_ = false;  // on a TLS connection, the bytes are not TLS: I/O (the refusal, the linger) on the TCP layer
  std::optional<PendingInput> answering_;  // busy lane: the request being answered, whose bytes are consumed

  std::shared_ptr<ResponseStream> body_stream_;  // a streamed answer's parts; closed with the session
  ResponseStream::Part part_;                    // the part being written
  bool streaming_ = false, writing_part_ = false, ending_ = false;
  std::optional<boost::asio::steady_timer> offer_timer_;  // a streamed answer waiting for its next part
  std::uint64_t offer_waits_ = 0;                         // which wait the timer's handler belongs to
};

}  // namespace rcand::http::detail
