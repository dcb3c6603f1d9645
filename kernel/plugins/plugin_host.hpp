// Finds plugins by their manifests, opens exactly the ones the robot needs, checks them against their
// manifests and records every outcome. Main thread only, except to_json() and format_table(), which any thread may
// call while reopen() runs on another.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "kernel/plugins/plugin_record.hpp"
#include "rcand/sdk/abi.h"

namespace rcand::kernel {

namespace detail {
class RecordingRegistrar;  // kernel/plugins/recording_registrar.hpp
}

class PluginHost {
 public:
  PluginHost() = default;
  ~PluginHost();  // removes the private reload directory (empty: each copy is unlinked once mapped)
  PluginHost(const PluginHost&) = delete;
  PluginHost& operator=(const PluginHost&) = delete;

  // Reads every *.json manifest in each directory, in path order then file-name order. Missing dirs are
  // skipped (logged). A second manifest with an id already seen is recorded `duplicate-id` (hint names the
  // first one's file). Invalid manifests are recorded `invalid-manifest`. Never throws for a plugin's fault.
  // Calling it again adds manifests not scanned yet.
  void scan(const std::vector<std::filesystem::path>& plugin_paths);

  // Installed plugins (valid manifests, not duplicates) whose manifest provides capability `name` / driver
  // `protocol`, in scan order.
  std::vector<const PluginRecord*> providers_of_capability(std::string_view name) const;
  std::vector<const PluginRecord*> providers_of_driver(std::string_view protocol) const;

  // Opens exactly the plugins that provide something needed (the first provider in scan order for each
  // name; other providers of the same name stay installed-not-enabled with a reason naming the chosen one).
  // Never throws for a plugin's fault: each opened plugin ends Loaded or in a failure state with reason and
  // hint. Plugins already opened by an earlier call are left as they are. With `capability_settings`
  // (runtime.capabilities), a plugin needed only for capabilities that run with `isolation: process` is not opened:
  // it is Loaded with what its manifest provides and no factories (its host process opens it, through these checks).
  void load_needed(const std::set<std::string>& capabilities, const std::set<std::string>& driver_protocols,
                   const nlohmann::json* capability_settings = nullptr);

  // A development reload of plugin `id`, once nothing of it runs (PluginRuntime::reload): its manifest re-read and
  // its library opened again from disk, through a private copy (a new file, so the loader cannot hand back the old
  // image; that one stays mapped, RTLD_NODELETE, so nothing the old version left behind can call into unmapped
  // code). The copy is made with O_EXCL|O_NOFOLLOW in a directory of rcand's own (mkdtemp, 0700, under the
  // reload directory's parent) and unlinked once mapped. The record ends Loaded or in a named failure state, as at
  // startup. Each reopen maps one more image for good: past kMaxReopens of one plugin it is refused
  // (FailedToOpen, "restart rcand"), so reloads cannot grow rcand's memory without bound. A plugin served apart has
  // only its manifest re-read: its capabilities' next host processes open the library.
  void reopen(std::string_view id);
  static constexpr int kMaxReopens = 16;
  // How many more times reopen(id) will map a new image.
  int reopens_left(std::string_view id) const;
  // Where reopen() makes its private directory: $RUNTIME_DIRECTORY when set (and not mounted noexec, where no
  // library could be mapped from), else `fallback` (rcand passes runtime.state_dir). Before the first reopen().
  void set_reload_parent(const std::filesystem::path& fallback);

  // How long a plugin's register() may take (runtime.plugin_start_timeout_ms): one that overruns is recorded
  // registration-failed and left running on its own thread. Applies to plugins opened after the call.
  void set_register_timeout(std::chrono::milliseconds timeout) noexcept { register_timeout_ = timeout; }

  const std::vector<std::unique_ptr<PluginRecord>>& records() const noexcept { return records_; }
  // The first record with this id (a duplicate-id record never comes first).
  PluginRecord* find(std::string_view id) noexcept;
  bool any_failed() const noexcept;

  // Aligned columns: ID, VERSION, STATE, PROVIDES, REASON / HINT. One line per plugin, header first.
  std::string format_table() const;
  // [{"id","version","state","reason","hint","provides":[{"kind","name","actuates","interface"}],"manifest",
  //   "build_info"}]
  // `with_paths` false (a caller who may not read the configuration): no manifest path or build info, and every
  // absolute path in a reason or hint shortened to its file name.
  nlohmann::json to_json(bool with_paths = true) const;

 private:
  void serve_apart(PluginRecord& record);
  void open(PluginRecord& record);
  void open_copy(PluginRecord& record);  // open() from a fresh copy of the library (reopen)
  // A private copy of `library` (see reopen); empty with `error` set when it cannot be made.
  std::filesystem::path private_copy(const std::filesystem::path& library, std::string& error);
  // The loader's steps; each one that refuses sets the record's state and returns false (or null).
  bool open_library(PluginRecord& record);
  const rcand_plugin_descriptor* read_descriptor(PluginRecord& record);
  std::shared_ptr<detail::RecordingRegistrar> run_register(PluginRecord& record, const rcand_plugin_descriptor& d);
  bool accept(PluginRecord& record, detail::RecordingRegistrar& registrar);

  std::vector<std::unique_ptr<PluginRecord>> records_;
  mutable std::mutex mutex_;  // a record's contents, while reopen() replaces them (the list itself never changes then)
  std::chrono::milliseconds register_timeout_{10000};
  std::filesystem::path reload_parent_, reload_dir_;  // reload_dir_: made by the first reopen()
  unsigned copies_ = 0;
  std::map<std::string, int, std::less<>> reopens_;  // per plugin id
};

}  // namespace rcand::kernel
