// Small files that must survive a crash or a power loss (rcand's state dir: the running marker, the e-stop latch
// record): whole-file reads, and replacements that leave either the old file or the new one, never a mix.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace rcand {

// The file's whole text; nullopt when it does not exist, empty when it cannot be read.
std::optional<std::string> read_whole_file(const std::filesystem::path& file);
// fsync of a directory (a rename or removal in it made durable); false when it failed.
bool fsync_directory(const std::filesystem::path& dir);
// Temp file `name`.tmp, write, fsync, rename over `name`, fsync the directory: after a crash the file is the old or
// the new one, whole. Returns an error text, empty when it worked.
std::string replace_file_durably(const std::filesystem::path& dir, const std::string& name, const std::string& text);

}  // namespace rcand
