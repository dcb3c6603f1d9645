#include "services/dashboard/dashboard_service.hpp"

#include <openssl/evp.h>

#include <map>

#include "kernel/api/answers.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/logging.hpp"
#include "services/dashboard/dashboard_assets.hpp"

namespace rcand::services {
namespace {

using kernel::Call;
using kernel::Reply;
using nlohmann::json;

// The page loads only what rcand serves (no CDN: it must work on a robot's offline LAN), talks only to rcand, and
// shows the camera stream; no framing, no sniffing, no referrer carrying a ?token= elsewhere.
const std::vector<std::pair<std::string, std::string>> kHeaders{
    {"Content-Security-Policy",
     "default-src 'self'; img-src 'self' blob: data:; connect-src 'self' ws: wss:; frame-ancestors 'none'; base-uri 'none'"},
    {"X-Content-Type-Options", "nosniff"},
    {"Referrer-Policy", "no-referrer"},
    {"Cache-Control", "no-cache"}};

std::string etag_of(const std::string& body) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  EVP_Digest(body.data(), body.size(), digest, &size, EVP_sha256(), nullptr);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string tag = "\"";
  for (unsigned int i = 0; i < 8 && i < size; ++i) tag += {kHex[digest[i] >> 4], kHex[digest[i] & 15]};
  return tag + "\"";
}

class DashboardService final : public kernel::Service {
 public:
  DashboardService() {
    for (const auto& asset : dashboard::assets()) files_.emplace(asset.name, File{&asset, etag_of(asset.body)});
  }

  std::string_view name() const noexcept override { return "dashboard"; }

  void add_routes(kernel::Router& router) override {
    router.add({"GET", "/", sdk::Scope::None}, [this](Call& call, Reply reply) { serve("index.html", call, reply); });
    router.add({"GET", "/dashboard/*", sdk::Scope::None}, [this](Call& call, Reply reply) {
      serve(call.request.path.substr(std::string_view("/dashboard/").size()), call, reply);
    });
    router.add({"GET", "/api/session", sdk::Scope::Status}, [](Call& call, Reply reply) {
      json scopes = json::array();
      for (auto scope : call.scopes) scopes.push_back(sdk::scope_name(scope));
      reply(kernel::json_response(200, {{"principal", call.principal}, {"role", sdk::role_name(call.role)}, {"scopes", scopes}}));
    });
  }

 private:
  struct File {
    const dashboard::Asset* asset;
    std::string etag;
  };

  void serve(const std::string& name, const Call& call, const Reply& reply) const {
    const auto it = files_.find(name);
    if (it == files_.end()) {
      reply(kernel::error_response(404, "NOT_FOUND", "no dashboard file " + bounded_text(name)));
      return;
    }
    http::Response response;
    response.headers = kHeaders;
    response.headers.emplace_back("ETag", it->second.etag);
    if (call.request.header("if-none-match") == std::optional<std::string_view>(it->second.etag)) {
      response.status = 304;
    } else {
      response.content_type = it->second.asset->content_type;
      response.body = it->second.asset->body;
    }
    reply(std::move(response));
  }

  std::map<std::string, File, std::less<>> files_;
};

}  // namespace

std::unique_ptr<kernel::Service> make_dashboard(kernel::ServiceHost&) { return std::make_unique<DashboardService>(); }

}  // namespace rcand::services
