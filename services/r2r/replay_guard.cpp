#include "services/r2r/replay_guard.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "libs/r2r_wire/message_signature.hpp"
#include "services/r2r/message_auth.hpp"

namespace rcand::services::r2r {

std::string replay_key(const nlohmann::json& message) {
  const std::string input = r2r_wire::signing_input(message);
  std::string digest(EVP_MAX_MD_SIZE, '\0');
  unsigned int length = 0;
  if (EVP_Digest(input.data(), input.size(), reinterpret_cast<unsigned char*>(digest.data()), &length, EVP_sha256(), nullptr) !=
      1)
    throw std::runtime_error("SHA-256 failed");
  digest.resize(length);
  return digest;
}

bool ReplayGuard::first_time(const std::string& key, double now_s) {
  if (now_s - last_prune_s_ >= 1.0 || seen_.size() >= max_entries_) prune(now_s);
  return seen_.emplace(key, now_s).second;
}

void ReplayGuard::prune(double now_s) {
  last_prune_s_ = now_s;
  std::erase_if(seen_, [&](const auto& entry) { return entry.second < now_s - window_s_; });
  if (seen_.size() < max_entries_) return;
  // Still full of fresh entries (a flood): forget the older half rather than grow without bound.
  std::vector<double> times;
  times.reserve(seen_.size());
  for (const auto& entry : seen_) times.push_back(entry.second);
  auto middle = times.begin() + static_cast<std::ptrdiff_t>(times.size() / 2);
  std::nth_element(times.begin(), middle, times.end());
  const double cutoff = *middle;
  std::erase_if(seen_, [&](const auto& entry) { return entry.second < cutoff; });
}

}  // namespace rcand::services::r2r
