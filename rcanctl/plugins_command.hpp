// rcanctl plugins reload ID: a development reload of one plugin in a running rcand (POST /api/plugins/<id>/reload).
#pragma once

#include <span>
#include <string>

namespace rcand::rcanctl {

// The words after "plugins reload". Exit: 0 reloaded, 1 refused or failed (the robot's code and reason on stderr;
// the plugin's state in the table or JSON), 2 usage.
int run_plugins_reload(std::span<const std::string> args);

}  // namespace rcand::rcanctl
