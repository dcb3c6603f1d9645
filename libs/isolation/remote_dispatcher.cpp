#include "libs/isolation/remote_dispatcher.hpp"

#include <utility>

#include "libs/isolation/wire.hpp"

namespace rcand::isolation {

using nlohmann::json;

namespace {

// The plugin's handle on a caller's credential: rcand forgets the credential when the plugin lets go of it.
class HostCredential final : public sdk::Credential {
 public:
  HostCredential(Channel& channel, std::uint64_t handle) : channel_(channel), handle_(handle) {}
  ~HostCredential() override { channel_.send({{"t", "cred_drop"}, {"cred", handle_}}, nullptr, /*wait=*/false); }
  std::uint64_t handle() const noexcept { return handle_; }

 private:
  Channel& channel_;
  const std::uint64_t handle_;
};

}  // namespace

RemoteDispatcher::RemoteDispatcher(Channel& channel) : channel_(channel), answers_("dispatch", [](const std::string&) {}) {}

RemoteDispatcher::~RemoteDispatcher() { join(); }

void RemoteDispatcher::join() {
  close();
  answers_.join();
}

void RemoteDispatcher::dispatch(sdk::Request request, sdk::Json audit_note,
                                std::function<void(sdk::Response)> done) const noexcept {
  try {
    const auto* credential = dynamic_cast<const HostCredential*>(request.credential.get());
    json message{{"t", "dispatch"},
                 {"req", encode_request(request)},
                 {"cred", credential != nullptr ? json(credential->handle()) : json()},
                 {"note", std::move(audit_note)}};
    std::uint64_t id = 0;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return answer(std::move(done), sdk::Response::error(503, "UNAVAILABLE", "rcand's channel is closed"));
      id = ++next_;
      waiting_[id] = done;
    }
    message["id"] = id;
    std::string error;
    if (channel_.send(message, &error, /*wait=*/false)) return;
    std::lock_guard lock(mutex_);
    waiting_.erase(id);
    answer(std::move(done), sdk::Response::error(503, "UNAVAILABLE", "the request could not reach rcand: " + error));
  } catch (const std::exception& e) {  // a body or note that cannot be encoded
    answer(std::move(done),
           sdk::Response::error(500, "INTERNAL", std::string("the request cannot be sent to rcand: ") + e.what()));
  }
}

void RemoteDispatcher::answered(const json& message) {
  std::function<void(sdk::Response)> done;
  {
    std::lock_guard lock(mutex_);
    const auto it = waiting_.find(message.at("id").get<std::uint64_t>());
    if (it == waiting_.end()) return;
    done = std::move(it->second);
    waiting_.erase(it);
  }
  answer(std::move(done), sdk::Response{message.at("status").get<int>(), message.at("body")});
}

void RemoteDispatcher::close() {
  std::map<std::uint64_t, std::function<void(sdk::Response)>> waiting;
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    waiting.swap(waiting_);
  }
  for (auto& [id, done] : waiting)
    answer(std::move(done), sdk::Response::error(503, "UNAVAILABLE", "rcand's channel closed before it answered"));
}

std::shared_ptr<const sdk::Credential> RemoteDispatcher::credential(const json& handle) {
  if (!handle.is_number_unsigned()) return nullptr;
  return std::make_shared<HostCredential>(channel_, handle.get<std::uint64_t>());
}

// Never on the caller's thread nor the channel's reader: `done` may dispatch again, or wait on rcand.
void RemoteDispatcher::answer(std::function<void(sdk::Response)> done, sdk::Response response) const {
  answers_.post([done = std::move(done), response = std::move(response)]() mutable { done(std::move(response)); });
}

json CredentialTable::keep(const std::shared_ptr<const sdk::Credential>& credential) {
  if (!credential) return nullptr;
  std::lock_guard lock(mutex_);
  if (credentials_.size() >= kMaxCredentials) credentials_.erase(credentials_.begin());
  credentials_[++next_] = credential;
  return next_;
}

std::shared_ptr<const sdk::Credential> CredentialTable::find(const json& handle) const {
  if (!handle.is_number_unsigned()) return nullptr;
  std::lock_guard lock(mutex_);
  const auto it = credentials_.find(handle.get<std::uint64_t>());
  return it != credentials_.end() ? it->second : nullptr;
}

void CredentialTable::drop(const json& handle) {
  if (!handle.is_number_unsigned()) return;
  std::lock_guard lock(mutex_);
  credentials_.erase(handle.get<std::uint64_t>());
}

void CredentialTable::clear() {
  std::lock_guard lock(mutex_);
  credentials_.clear();
}

void dispatch_for_host(const sdk::RequestDispatcher* dispatcher, const CredentialTable& credentials, const json& message,
                       std::shared_ptr<Channel> channel) {
  const json& id = message.at("id");
  const auto send = [channel, id](const sdk::Response& response) {
    channel->send({{"t", "dispatched"}, {"id", id}, {"status", response.status}, {"body", response.body}}, nullptr,
                  /*wait=*/false);
  };
  if (dispatcher == nullptr) return send(sdk::Response::error(503, "UNAVAILABLE", "this rcand offers no request dispatcher"));
  sdk::Request request = decode_request(message.at("req"));
  request.credential = credentials.find(message.at("cred"));  // rcand's own: the host's word is only a handle
  dispatcher->dispatch(std::move(request), message.at("note"), send);
}

}  // namespace rcand::isolation
