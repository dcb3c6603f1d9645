#include "libs/config/config_access.hpp"

#include <utility>

namespace rcand::config {

std::vector<std::string> config_access_problems(const RobotConfig& config, const std::filesystem::path& config_file,
                                                const std::vector<std::filesystem::path>& plugin_paths,
                                                const UserIdentity& user) {
  std::vector<std::pair<std::filesystem::path, Access>> needed{{config_file, Access::Read},
                                                               {config.runtime.state_dir, Access::Write}};
  for (const auto& fragment : config.fragment_files) needed.emplace_back(fragment, Access::Read);
  if (config.runtime.auth.jwt_secret_file) needed.emplace_back(*config.runtime.auth.jwt_secret_file, Access::Read);
  if (config.runtime.audit_file) needed.emplace_back(*config.runtime.audit_file, Access::Write);
  if (const auto& tls = config.runtime.listen_tls) {
    needed.insert(needed.end(), {{tls->cert_file, Access::Read}, {tls->key_file, Access::Read}});
    if (tls->client_ca_file) needed.emplace_back(*tls->client_ca_file, Access::Read);
  }
  if (std::filesystem::exists(config.runtime.swarm_file)) needed.emplace_back(config.runtime.swarm_file, Access::Read);
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
  std::vector<std::filesystem::path> files{config.source_file, config.runtime.state_dir, config.runtime.swarm_file};
  files.insert(files.end(), config.fragment_files.begin(), config.fragment_files.end());
  if (config.runtime.audit_file) files.push_back(*config.runtime.audit_file);
  if (config.runtime.auth.jwt_secret_file) files.push_back(*config.runtime.auth.jwt_secret_file);
  if (config.runtime.listen_tls) files.push_back(config.runtime.listen_tls->key_file);
  return files;
}

}  // namespace rcand::config
