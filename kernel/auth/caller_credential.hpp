// The credential a request to a plugin came with (sdk::Credential, Request::credential): kept so that rcand can
// authorize the caller again when a plugin acts on the caller's behalf later (RequestDispatcher, a human-approved chat
// action minutes afterwards). Made only by the kernel, for each request it hands a capability; the bearer stays on the
// kernel's side of the interface (plugins see an opaque sdk::Credential) and is never logged.
#pragma once

#include <rcand/sdk/http.hpp>

#include <optional>
#include <string>
#include <string_view>

namespace rcand::kernel {

class CallerCredential final : public sdk::Credential {
 public:
  // `bearer`: the token or JWT the request carried; nullopt when it carried none (open mode on loopback).
  explicit CallerCredential(std::optional<std::string_view> bearer) {
    if (bearer) bearer_ = std::string(*bearer);
  }
  const std::optional<std::string>& bearer() const noexcept { return bearer_; }

 private:
  std::optional<std::string> bearer_;
};

}  // namespace rcand::kernel
