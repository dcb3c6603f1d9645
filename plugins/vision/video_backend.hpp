// The real camera sources (file, V4L2 device, URL) live in a module of their own, rcand_vision_videoio.so, installed
// beside the vision plugin (same package): it is the only part that links OpenCV's videoio and, through it, FFmpeg
// and GStreamer. The plugin loads it on the first such source, from the directory the plugin itself was loaded from
// (the build tree's plugins/ in tests, the package's plugin directory when installed), and keeps it loaded. A robot
// on the synthetic camera never maps a video backend (issue 32). A missing module is a named fault, never a
// fallback.
#pragma once

#include <filesystem>
#include <memory>

#include "camera_source.hpp"

// The module's entry symbol, versioned with the interface it is called through (FrameSource, SourceSettings).
#define RCAND_VISION_VIDEOIO_ENTRY rcand_vision_videoio_source_v2

namespace rcand::plugins::vision {

inline constexpr const char* kVideoModuleName = "rcand_vision_videoio.so";

// Where the module is looked for: beside the library (or executable) this code is linked into.
std::filesystem::path video_module_path();

// A file, device or URL source from the module. Throws SourceError naming the module when it is missing or cannot
// be loaded (its OpenCV or FFmpeg libraries missing).
std::unique_ptr<FrameSource> make_video_source(const SourceSettings& settings);

}  // namespace rcand::plugins::vision
