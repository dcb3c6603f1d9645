// sdk::RequestDispatcher across an isolated capability's channel (chat turning an instruction into a robot command). A
// caller's credential never leaves rcand: a request sent to the host carries a handle to it instead, which the host's
// Request::credential holds (HostCredential) and hands back with a dispatch; rcand then dispatches with the credential
// it kept, authorizing the caller again as in process. A handle the host lets go (the Credential destroyed) is
// forgotten in rcand; rcand keeps at most kMaxCredentials of them (the oldest forgotten first: its dispatch is then
// refused 401 as one without a credential).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>

#include "libs/base/worker_thread.hpp"
#include "libs/isolation/channel.hpp"
#include "rcand/sdk/interfaces/request_dispatcher.hpp"

namespace rcand::isolation {

// The host's side: what the plugin finds as rcand.request_dispatcher/3.
class RemoteDispatcher final : public sdk::RequestDispatcher {
 public:
  explicit RemoteDispatcher(Channel& channel);
  ~RemoteDispatcher() override;  // answers every dispatch still waiting (503), then ends its worker

  void dispatch(sdk::Request request, sdk::Json audit_note, std::function<void(sdk::Response)> done) const noexcept override;
  // rcand's "dispatched" message: the answer of one dispatch, given to its `done` on a worker of its own.
  void answered(const nlohmann::json& message);
  // The channel ended: every dispatch still waiting gets 503.
  void close();
  // close(), then every answer given: before the plugin's objects, which its `done` callbacks use, are destroyed.
  void join();
  // A request from rcand, with the handle of its caller's credential (none: null), as the plugin gets it.
  std::shared_ptr<const sdk::Credential> credential(const nlohmann::json& handle);

 private:
  void answer(std::function<void(sdk::Response)> done, sdk::Response response) const;
  Channel& channel_;
  mutable std::mutex mutex_;
  mutable std::uint64_t next_ = 0;
  mutable std::map<std::uint64_t, std::function<void(sdk::Response)>> waiting_;
  mutable bool closed_ = false;
  mutable WorkerThread answers_;
};

// rcand's side: the credentials of requests sent to the host, by handle.
class CredentialTable {
 public:
  static constexpr std::size_t kMaxCredentials = 4096;
  // The handle for `credential` (null: no handle, json null).
  nlohmann::json keep(const std::shared_ptr<const sdk::Credential>& credential);
  std::shared_ptr<const sdk::Credential> find(const nlohmann::json& handle) const;
  void drop(const nlohmann::json& handle);
  void clear();

 private:
  mutable std::mutex mutex_;
  std::uint64_t next_ = 0;
  std::map<std::uint64_t, std::shared_ptr<const sdk::Credential>> credentials_;
};

// rcand: a host's "dispatch" message run through rcand's own dispatcher (null: rcand offers none, 503), its answer sent
// back as "dispatched" when it comes. Throws nlohmann's exception for a message that does not decode.
void dispatch_for_host(const sdk::RequestDispatcher* dispatcher, const CredentialTable& credentials,
                       const nlohmann::json& message, std::shared_ptr<Channel> channel);

}  // namespace rcand::isolation
