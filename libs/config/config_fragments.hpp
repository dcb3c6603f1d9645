// /etc/rcand/conf.d/: drop-in fragments over the robot's config, so a package, a provisioning tool or an admin can
// change one setting without editing (and conflicting on upgrade with) the packaged robot.rcan.yaml. Fragments are
// the `*.yaml` files in the `conf.d` directory beside the main file, merged in name order ("10-network.yaml" before
// "50-site.yaml") as JSON Merge Patches (RFC 7396): mappings merge key by key, `null` removes a key, anything else
// (a scalar, a list) replaces what was there. The merged document is validated as one file, and every key a fragment
// wrote keeps the fragment's own file:line:column, so an error names the file that made it.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "libs/yaml/yaml_document.hpp"

namespace rcand::config {

using yaml::ConfigDiagnostic;
using yaml::SourceMark;

// The fragments for `config_file`: <its directory>/conf.d/*.yaml, sorted by file name; none when there is no such
// directory. Hidden files and anything else (editor backups, *.dpkg-old) are not read.
std::vector<std::filesystem::path> config_fragment_files(const std::filesystem::path& config_file);

// Merges `fragment` into `base` (both parsed, ok) and carries the fragment's marks for what it wrote; marks under
// a key it removed or replaced are dropped. A fragment that is not a mapping is an error in `diagnostics` (and
// merges nothing).
void merge_config_fragment(yaml::YamlDocument& base, const yaml::YamlDocument& fragment, const std::string& fragment_name,
                           std::vector<ConfigDiagnostic>& diagnostics);

}  // namespace rcand::config
