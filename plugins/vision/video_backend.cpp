#include "video_backend.hpp"

#include <dlfcn.h>

#include <mutex>
#include <system_error>

namespace rcand::plugins::vision {
namespace {

using MakeVideoSource = FrameSource* (*)(const SourceSettings&) noexcept;

#define RCAND_VISION_STRINGIFY2(x) #x
#define RCAND_VISION_STRINGIFY(x) RCAND_VISION_STRINGIFY2(x)

// Loaded once, never unloaded (RTLD_NODELETE): FFmpeg and GStreamer do not survive dlclose, and a source from the
// module may outlive any one plugin instance.
MakeVideoSource load_video_module() {
  static std::mutex mutex;
  static MakeVideoSource make = nullptr;
  std::lock_guard lock(mutex);
  if (make) return make;
  const auto path = video_module_path();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw SourceError(std::string("the video backend module ") + kVideoModuleName + " is not installed: " + path.string() +
                      " does not exist (it comes with the vision plugin, package rcand-plugins-vision)");
  void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
  if (!handle) {
    const char* why = ::dlerror();
    throw SourceError(std::string("the video backend module ") + path.string() +
                      " could not be loaded: " + (why ? why : "unknown error"));
  }
  void* entry = ::dlsym(handle, RCAND_VISION_STRINGIFY(RCAND_VISION_VIDEOIO_ENTRY));
  if (!entry)
    throw SourceError(std::string("the video backend module ") + path.string() + " is not this vision plugin's version (no " +
                      RCAND_VISION_STRINGIFY(RCAND_VISION_VIDEOIO_ENTRY) + ")");
  make = reinterpret_cast<MakeVideoSource>(entry);
  return make;
}

}  // namespace

std::filesystem::path video_module_path() {
  Dl_info info{};
  if (::dladdr(reinterpret_cast<void*>(&video_module_path), &info) == 0 || !info.dli_fname)
    throw SourceError("the video backend module cannot be located: dladdr failed on the vision plugin itself");
  return std::filesystem::path(info.dli_fname).parent_path() / kVideoModuleName;
}

std::unique_ptr<FrameSource> make_video_source(const SourceSettings& settings) {
  std::unique_ptr<FrameSource> source(load_video_module()(settings));
  if (!source)
    throw SourceError("the video backend module made no " + std::string(kind_name(settings.kind)) + " source (out of memory?)");
  return source;
}

}  // namespace rcand::plugins::vision
