#include "libs/config/config_access.hpp"

#include <utility>

namespace rcand::config {
namespace {

struct NamedFile {
  std::filesystem::path path;
  Access access;          // what rcand needs of it
  bool private_to_rcand;  // no other process of the robot needs it (secrets, the latch's state, peers' tokens)
};

// Every file of rcand's own that a config names, once: the one list both the access check and the isolation use.
std::vector<NamedFile> named_files(const RobotConfig& config) {
  std::vector<NamedFile> files{{config.source_file, Access::Read, true},
                               {config.runtime.state_dir, Access::Write, true},
                               {config.runtime.swarm_file, Access::Read, true}};
  for (const auto& fragment : config.fragment_files) files.push_back({fragment, Access::Read, true});
  if (config.runtime.auth.jwt_secret_file) files.push_back({*config.runtime.auth.jwt_secret_file, Access::Read, true});
  if (config.runtime.audit_file) files.push_back({*config.runtime.audit_file, Access::Write, true});
  if (const auto& tls = config.runtime.listen_tls) {
    files.push_back({tls->cert_file, Access::Read, false});
    files.push_back({tls->key_file, Access::Read, true});
    if (tls->client_ca_file) files.push_back({*tls->client_ca_file, Access::Read, false});
  }
  return files;
}

}  // namespace

std::vector<std::string> config_access_problems(const RobotConfig& config, const std::vector<std::filesystem::path>& plugin_paths,
                                                const UserIdentity& user) {
  std::vector<std::pair<std::filesystem::path, Access>> needed;
  for (const auto& file : named_files(config))  // the swarm file is optional: only one that exists must be readable
    if (file.path != config.runtime.swarm_file || std::filesystem::exists(file.path)) needed.emplace_back(file.path, file.access);
  for (const auto& dir : plugin_paths)
    if (std::filesystem::exists(dir)) needed.emplace_back(dir, Access::Read);
  // Devices: any driver setting or camera key that names one.
  std::vector<nlohmann::json> holders;
  for (const auto& driver : config.drivers) holders.push_back(driver.settings);
  if (config.doc.contains("camera")) holders.push_back(config.doc["camera"]);
  for (const auto& holder : holders)
    if (holder.is_object())
      for (const auto& [key, value] : holder.items())
        if (value.is_string() && value.get<std::string>().starts_with("/dev/"))
          needed.emplace_back(value.get<std::string>(), Access::ReadWrite);
  std::vector<std::string> problems;
  for (const auto& [path, access] : needed)
    if (auto problem = access_problem(user, path, access); !problem.empty()) problems.push_back(std::move(problem));
  return problems;
}

std::vector<std::filesystem::path> private_files(const RobotConfig& config) {
  std::vector<std::filesystem::path> files;
  for (auto& file : named_files(config))
    if (file.private_to_rcand) files.push_back(std::move(file.path));
  return files;
}

}  // namespace rcand::config
