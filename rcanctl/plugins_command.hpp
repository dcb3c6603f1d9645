// rcanctl plugins reload ID: a development reload of one plugin in a running rcand (POST /api/plugins/<id>/reload).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "robot_connection.hpp"

namespace rcand::rcanctl {

// Declares `reload ID` under `rcanctl plugins` (the ID into `id`); the connection options are the caller's to add.
CLI::App* add_plugins_reload(CLI::App& plugins, std::string& id);

// Exit: 0 reloaded, 1 refused or failed (the robot's code and reason on stderr; the plugin's state in the table or
// JSON).
int run_plugins_reload(const std::string& id, const RobotOptions& options);

}  // namespace rcand::rcanctl
