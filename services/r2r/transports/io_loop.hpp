// A transport's network thread: runs its io_context until stopped. A handler that throws is logged and the loop
// goes on, so one bad message never silences a transport.
#pragma once

#include <spdlog/logger.h>
#include <boost/asio/io_context.hpp>

#include <exception>
#include <memory>
#include <string_view>
#include <thread>

namespace rcand::kernel::r2r {

inline std::thread start_io_loop(boost::asio::io_context& ioc, std::shared_ptr<spdlog::logger> log, std::string_view what) {
  return std::thread([&ioc, log = std::move(log), what] {
    for (;;) {
      try {
        ioc.run();
        return;
      } catch (const std::exception& e) {
        log->error("{}: {}", what, e.what());
      }
    }
  });
}

}  // namespace rcand::kernel::r2r
