// rcand --check-config --as-user: what a user could not open of the files and devices a config names (the service
// runs as `rcand`, not as the admin who edits the config).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "libs/base/user_access.hpp"
#include "libs/config/robot_config.hpp"

namespace rcand::config {

// One line per path `user` lacks the access it needs to: the config file (as loaded), its conf.d fragments, the
// state dir, the secrets, TLS files, swarm file and audit log it names, the plugin directories, and every /dev/ path
// a driver setting or the camera names.
std::vector<std::string> config_access_problems(const RobotConfig& config, const std::vector<std::filesystem::path>& plugin_paths,
                                                const UserIdentity& user);

// rcand's own files a config names, which no other process of the robot needs: the config and its fragments, the
// state dir, the audit log, the JWT secret, the TLS key and the swarm file (peers' tokens). An isolated capability's
// process is kept out of them (libs/isolation/file_access.hpp).
std::vector<std::filesystem::path> private_files(const RobotConfig& config);

}  // namespace rcand::config
