// A response body that is written part by part after the header, for as long as the producer pushes (an MJPEG
// stream). The producer and the Session share it: the producer pushes from any thread, the Session takes parts on
// its loop and writes them. At most one part waits: a part pushed before the previous one was taken replaces it (a
// drop), so a client that reads slowly skips parts and costs at most one part of memory, and the producer never
// waits for it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace rcand::http {

class ResponseStream {
 public:
  // Written as head, *data, tail: `data` is shared with every other client of the same frame, never copied.
  struct Part {
    std::string head;
    std::shared_ptr<const std::string> data;
    std::string tail;
    std::size_t size() const noexcept { return head.size() + (data ? data->size() : 0) + tail.size(); }
  };
  struct Counters {
    std::uint64_t sent = 0, dropped = 0, bytes = 0;
  };

  // ---- the producer: any thread, never blocks beyond a brief lock ----
  // false once closed or ended (the part is not kept).
  bool push(Part part);
  // No more parts: the Session writes the pending one, if any, then closes the connection.
  void end();
  // The client left, a write failed or stalled, no part came for a while, or the server stopped.
  bool closed() const;
  Counters counters() const;
  // Keeps `held` (the stream's slot, kernel/auth/slots.hpp) until the stream is closed or destroyed.
  void hold(std::shared_ptr<void> held);

  // ---- the Session, on its loop ----
  // `wake` is called (from push() or end(), on the producer's thread) when the Session waits for a part; it must
  // only post to the Session's loop.
  void attach(std::function<void()> wake);
  enum class Next { Part, Wait, End };
  // The pending part (Part), nothing yet (Wait: wake is armed), or the end (End).
  Next next(Part& out);
  void written(std::size_t bytes);
  void close() noexcept;

 private:
  mutable std::mutex mutex_;
  std::optional<Part> pending_;
  std::function<void()> wake_;
  std::shared_ptr<void> held_;
  bool armed_ = false, ended_ = false, closed_ = false;
  Counters counters_;
};

}  // namespace rcand::http
