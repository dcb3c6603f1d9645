// The `.rcan.yaml` schema as text, for `--help-config` style output: generated from the same table that validates.
#pragma once

#include <string>

namespace rcand::config {

// One line per known key: "path  type  required|default <v>|optional  description". "drivers[]" is any item of the
// drivers list; "runtime.capabilities.*" any capability name.
std::string config_reference();

}  // namespace rcand::config
