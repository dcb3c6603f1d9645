#include "libs/http/response_stream.hpp"

#include <utility>

namespace rcand::http {

bool ResponseStream::push(Part part) {
  std::function<void()> wake;
  {
    std::lock_guard lock(mutex_);
    if (closed_ || ended_) return false;
    if (pending_) ++counters_.dropped;
    pending_ = std::move(part);
    if (armed_) {
      armed_ = false;
      wake = wake_;
    }
  }
  if (wake) wake();  // outside the lock: it posts to the Session's loop
  return true;
}

void ResponseStream::end() {
  std::function<void()> wake;
  {
    std::lock_guard lock(mutex_);
    if (ended_) return;
    ended_ = true;
    if (armed_) {
      armed_ = false;
      wake = wake_;
    }
  }
  if (wake) wake();
}

bool ResponseStream::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

ResponseStream::Counters ResponseStream::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

void ResponseStream::attach(std::function<void()> wake) {
  std::lock_guard lock(mutex_);
  wake_ = std::move(wake);
}

ResponseStream::Next ResponseStream::next(Part& out) {
  std::lock_guard lock(mutex_);
  if (pending_) {
    out = std::move(*pending_);
    pending_.reset();
    return Next::Part;
  }
  if (ended_ || closed_) return Next::End;
  armed_ = true;
  return Next::Wait;
}

void ResponseStream::written(std::size_t bytes) {
  std::lock_guard lock(mutex_);
  ++counters_.sent;
  counters_.bytes += bytes;
}

void ResponseStream::hold(std::shared_ptr<void> held) {
  std::lock_guard lock(mutex_);
  if (!closed_) held_ = std::move(held);
}

void ResponseStream::close() noexcept {
  std::shared_ptr<void> held;
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    pending_.reset();
    armed_ = false;
    wake_ = nullptr;  // drops what the wake holds (a weak reference to the Session)
    held = std::move(held_);
  }
}  // `held` goes outside the lock

}  // namespace rcand::http
