// The service manager's side channel (sd_notify(3) protocol, without libsystemd): READY/RELOADING/STOPPING/WATCHDOG
// datagrams to $NOTIFY_SOCKET, and the watchdog interval systemd asks for. Outside systemd every call does nothing.
#pragma once

#include <chrono>
#include <optional>
#include <string_view>

namespace rcand {

// Sends `state` ("READY=1", "WATCHDOG=1", ...) when $NOTIFY_SOCKET is set; false when unset or the send failed.
bool notify_service_manager(std::string_view state) noexcept;

// WatchdogSec= of the unit ($WATCHDOG_USEC, when $WATCHDOG_PID is unset or this process); nullopt: no watchdog.
std::optional<std::chrono::microseconds> service_watchdog_interval() noexcept;

// Whether stderr is the journal's stream ($JOURNAL_STREAM names stderr's device and inode): log lines then carry
// their priority as a "<N>" prefix and no timestamp (journald adds its own).
bool stderr_is_journal() noexcept;

}  // namespace rcand
