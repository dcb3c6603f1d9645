#include "kernel/plugins/plugin_host.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <boost/dll/shared_library.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>

#include "kernel/plugins/descriptor_check.hpp"
#include "kernel/plugins/guarded.hpp"
#include "kernel/plugins/recording_registrar.hpp"
#include "libs/base/bounded_call.hpp"
#include "libs/base/string_list.hpp"
#include "libs/manifest/served_apart.hpp"

namespace rcand::kernel {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

void set_state(PluginRecord& record, PluginState state, std::string reason, std::string hint) {
  record.state = state;
  record.reason = std::move(reason);
  record.hint = std::move(hint);
  if (is_failure(state))
    plugins_logger()->error("plugin {} ({}): {}: {}", record.id, record.manifest_file.string(), to_string(state), record.reason);
}

bool installed(const PluginRecord& record) {
  return record.manifest.has_value() && record.state != PluginState::DuplicateId && record.state != PluginState::InvalidManifest;
}

bool provides(const PluginRecord& record, std::string_view kind, std::string_view name) {
  return std::any_of(record.manifest->provides.begin(), record.manifest->provides.end(),
                     [&](const ProvidedItem& item) { return item.kind == kind && item.name == name; });
}

std::string describe(const ProvidedItem& item) {
  std::string text = item.kind + " '" + item.name + "' (actuates=" + (item.actuates ? "true" : "false");
  if (!item.interface.empty()) text += ", interface=" + item.interface;
  return text + ")";
}

// What differs between the manifest's "provides" and what register() did, one sentence per difference.
std::vector<std::string> provides_differences(const std::vector<ProvidedItem>& manifest,
                                              const std::vector<ProvidedItem>& registered) {
  std::vector<std::string> out;
  const auto same_name = [](const ProvidedItem& a) {
    return [&a](const ProvidedItem& b) { return a.kind == b.kind && a.name == b.name; };
  };
  for (const auto& item : registered) {
    const auto it = std::find_if(manifest.begin(), manifest.end(), same_name(item));
    if (it == manifest.end()) out.push_back("registered " + item.kind + " '" + item.name + "' not in manifest");
    else if (!(*it == item)) out.push_back("registered " + describe(item) + " but manifest says " + describe(*it));
  }
  for (const auto& item : manifest)
    if (std::none_of(registered.begin(), registered.end(), same_name(item)))
      out.push_back("manifest provides " + item.kind + " '" + item.name + "' but the plugin did not register it");
  return out;
}

// The loader's own words (undefined symbol, wrong ELF class, ...). Boost.DLL only reports "bad file
// descriptor", but the failed dlopen's message is still pending in dlerror().
std::string loader_message(const std::error_code& ec) {
  const char* message = ::dlerror();
  return message != nullptr ? std::string(message) : ec.message();
}

}  // namespace

void PluginHost::scan(const std::vector<fs::path>& plugin_paths) {
  auto log = plugins_logger();
  std::map<std::string, const PluginRecord*> first_by_id;
  std::vector<fs::path> known;
  for (const auto& record : records_) {
    known.push_back(record->manifest_file);
    if (installed(*record)) first_by_id.emplace(record->id, record.get());
  }

  for (const auto& dir : plugin_paths) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
      log->warn("plugin path {} is not a directory; skipped", dir.string());
      continue;
    }
    std::vector<fs::path> manifests;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      std::error_code type_ec;
      if (it->path().extension() == ".json" && it->is_regular_file(type_ec)) manifests.push_back(it->path());
    }
    if (ec) log->warn("cannot list plugin path {}: {}", dir.string(), ec.message());
    std::sort(manifests.begin(), manifests.end(),
              [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });

    for (const auto& file : manifests) {
      const fs::path normal = fs::absolute(file, ec).lexically_normal();
      if (std::find(known.begin(), known.end(), normal) != known.end()) continue;  // scanned before
      known.push_back(normal);

      auto record = std::make_unique<PluginRecord>();
      record->manifest_file = normal;
      try {
        record->manifest = load_manifest(normal);
        record->id = record->manifest->id;
        record->version = record->manifest->version;
      } catch (const std::exception& e) {
        record->id = normal.filename().string();  // something to show; the manifest's id is not trustworthy
        set_state(*record, PluginState::InvalidManifest, e.what(), "fix the manifest (format: manifests/manifest.schema.json)");
        records_.push_back(std::move(record));
        continue;
      }
      if (const auto first = first_by_id.find(record->id); first != first_by_id.end()) {
        set_state(*record, PluginState::DuplicateId,
                  "id '" + record->id + "' is already used by " + first->second->manifest_file.string(),
                  "remove one of the two plugins (first: " + first->second->manifest_file.string() + ")");
      } else {
        first_by_id.emplace(record->id, record.get());
        log->debug("found plugin {} {} ({})", record->id, record->version, normal.string());
      }
      records_.push_back(std::move(record));
    }
  }
}

std::vector<const PluginRecord*> PluginHost::providers_of_capability(std::string_view name) const {
  std::vector<const PluginRecord*> out;
  for (const auto& record : records_)
    if (installed(*record) && provides(*record, "capability", name)) out.push_back(record.get());
  return out;
}

std::vector<const PluginRecord*> PluginHost::providers_of_driver(std::string_view protocol) const {
  std::vector<const PluginRecord*> out;
  for (const auto& record : records_)
    if (installed(*record) && provides(*record, "driver", protocol)) out.push_back(record.get());
  return out;
}

void PluginHost::load_needed(const std::set<std::string>& capabilities, const std::set<std::string>& driver_protocols,
                             const json* capability_settings) {
  std::set<const PluginRecord*> chosen;
  std::map<const PluginRecord*, std::string> passed_over;  // provider -> why another one was chosen
  const auto choose = [&](std::string_view kind, const std::string& name, std::vector<const PluginRecord*> providers) {
    if (providers.empty()) return;
    chosen.insert(providers.front());
    for (std::size_t i = 1; i < providers.size(); ++i)
      passed_over.emplace(providers[i], std::string(kind) + " '" + name + "' is provided by " + providers.front()->id + " (" +
                                            providers.front()->manifest_file.filename().string() + "), first in scan order");
  };
  for (const auto& name : capabilities) choose("capability", name, providers_of_capability(name));
  for (const auto& protocol : driver_protocols) choose("driver", protocol, providers_of_driver(protocol));

  // Scan order, so the first provider of a name is also the first to register it.
  for (const auto& record : records_) {
    if (record->state != PluginState::InstalledNotEnabled || !installed(*record)) continue;
    if (record->library) continue;  // opened before
    if (chosen.count(record.get()) != 0 && capability_settings != nullptr &&
        served_apart(*record->manifest, capabilities, driver_protocols, *capability_settings)) {
      serve_apart(*record);
    } else if (chosen.count(record.get()) != 0) {
      open(*record);
    } else if (const auto it = passed_over.find(record.get()); it != passed_over.end()) {
      set_state(*record, PluginState::InstalledNotEnabled, it->second, "remove one of the providers to choose the other");
    } else {
      std::vector<std::string> names;
      for (const auto& item : record->manifest->provides) names.push_back(item.kind + " '" + item.name + "'");
      set_state(*record, PluginState::InstalledNotEnabled, "not needed: the robot config uses none of what it provides",
                "to enable it, configure " + join(names, " or "));
    }
  }
}

// Loaded from its manifest, opened by no one in rcand: its capabilities' host processes open it.
void PluginHost::serve_apart(PluginRecord& record) {
  for (const auto& item : record.manifest->provides)
    if (item.kind == "capability") record.capabilities.push_back({{item.name, item.actuates}, nullptr});
  record.abi_minor = RCAND_ABI_MINOR;  // what rcand calls is its own proxy (libs/isolation)
  record.build_info = "opened by rcand-plugin-host (isolation: process)";
  set_state(record, PluginState::Loaded, "", "");
}

// The loader is a straight line of refusals, each one a state, a reason and a hint: open the library, read its
// descriptor, run its register(), accept what it registered.
void PluginHost::open(PluginRecord& record) {
  if (!open_library(record)) return;
  const rcand_plugin_descriptor* descriptor = read_descriptor(record);
  if (descriptor == nullptr) return;
  auto registrar = run_register(record, *descriptor);
  if (registrar == nullptr || !accept(record, *registrar)) return;
  plugins_logger()->info("loaded plugin {} {} ({})", record.id, record.version, record.manifest->library.string());
}

bool PluginHost::open_library(PluginRecord& record) {
  const PluginManifest& manifest = *record.manifest;
  const std::string lib = manifest.library.string();
  if (manifest.abi_major != RCAND_ABI_MAJOR)
    return set_state(record, PluginState::IncompatibleAbi,
                     "manifest declares ABI " + std::to_string(manifest.abi_major) + ", kernel speaks " +
                         std::to_string(RCAND_ABI_MAJOR) + " (library not opened)",
                     rebuild_hint()),
           false;
  std::error_code ec;
  if (!fs::exists(manifest.library, ec))
    return set_state(record, PluginState::FailedToOpen, "library " + lib + " not found",
                     "install " + manifest.library.filename().string() + " next to " + manifest.file.filename().string() +
                         ", or fix its \"library\" field"),
           false;
  auto library = std::make_shared<boost::dll::shared_library>();
  try {
    // RTLD_NOW: a missing symbol fails here, never mid-motion. RTLD_LOCAL: plugins cannot see each
    // other's symbols. RTLD_NODELETE: code is never unmapped, even if every handle were dropped.
    const auto mode = static_cast<boost::dll::load_mode::type>(boost::dll::load_mode::rtld_now |
                                                               boost::dll::load_mode::rtld_local | RTLD_NODELETE);
    ::dlerror();  // clear a stale message so the one we read is this load's
    library->load(manifest.library, ec, mode);
    if (ec || !library->is_loaded())
      return set_state(record, PluginState::FailedToOpen, "cannot open " + lib + ": " + loader_message(ec),
                       "run `ldd -r " + lib + "`"),
             false;
  } catch (const std::exception& e) {
    return set_state(record, PluginState::FailedToOpen, "cannot open " + lib + ": " + e.what(), "run `ldd -r " + lib + "`"),
           false;
  }
  record.library = library;  // from here on the handle stays, whatever the outcome
  return true;
}

const rcand_plugin_descriptor* PluginHost::read_descriptor(PluginRecord& record) {
  auto& library = *std::static_pointer_cast<boost::dll::shared_library>(record.library);
  const std::string lib = record.manifest->library.string();
  if (!library.has(RCAND_ENTRY_SYMBOL)) {
    for (int major = 1; major <= 9; ++major) {
      if (major == RCAND_ABI_MAJOR) continue;
      if (library.has("rcand_plugin_entry_v" + std::to_string(major)))
        return set_state(record, PluginState::IncompatibleAbi,
                         "built for ABI " + std::to_string(major) + ", kernel speaks " + std::to_string(RCAND_ABI_MAJOR),
                         rebuild_hint()),
               nullptr;
    }
    return set_state(record, PluginState::FailedToOpen, std::string("no entry symbol ") + RCAND_ENTRY_SYMBOL + " in " + lib,
                     "build it with RCAND_PLUGIN"),
           nullptr;
  }
  const auto entry = library.template get<const rcand_plugin_descriptor*()>(RCAND_ENTRY_SYMBOL);
  std::string failure;
  const auto descriptor = guarded_result(record.id, "entry point", failure, [&] { return entry(); });
  if (!descriptor)
    return set_state(record, PluginState::RegistrationFailed, "entry point threw: " + failure,
                     "the entry point must only return its static descriptor: build it with RCAND_PLUGIN"),
           nullptr;
  if (auto verdict = check_descriptor(*descriptor, *record.manifest))
    return set_state(record, verdict->state, std::move(verdict->reason), std::move(verdict->hint)), nullptr;
  if ((*descriptor)->build_info != nullptr) record.build_info = (*descriptor)->build_info;
  record.abi_minor = (*descriptor)->abi_minor;
  return *descriptor;
}

// register() on a thread of its own, bounded: a plugin stuck in it fails alone instead of keeping the robot from ever
// starting. The registrar and the failure text are shared with that thread, which may outlive this call.
std::shared_ptr<detail::RecordingRegistrar> PluginHost::run_register(PluginRecord& record, const rcand_plugin_descriptor& d) {
  struct Registration {
    std::shared_ptr<detail::RecordingRegistrar> registrar = std::make_shared<detail::RecordingRegistrar>();
    std::string failure;
    bool returned = false;
  };
  auto registration = std::make_shared<Registration>();
  const bool finished =
      bounded_call("plugin.register", register_timeout_, [registration, who = record.id, register_plugin = d.register_plugin] {
        sdk::Registrar& base = *registration->registrar;
        registration->returned = guarded_call(who, "register", registration->failure,
                                              [&] { register_plugin(reinterpret_cast<rcand_registrar*>(&base)); });
      });
  if (!finished)
    return set_state(record, PluginState::RegistrationFailed,
                     "register() did not return within " + std::to_string(register_timeout_.count()) +
                         " ms (runtime.plugin_start_timeout_ms)",
                     "see the plugin's log: its register function must only register factories"),
           nullptr;
  if (!registration->returned)
    return set_state(record, PluginState::RegistrationFailed, "register threw: " + registration->failure,
                     "see the plugin's log and fix its register function"),
           nullptr;
  if (!registration->registrar->errors.empty())
    return set_state(record, PluginState::RegistrationFailed, join(registration->registrar->errors, "; "),
                     "fix the plugin's register function"),
           nullptr;
  return registration->registrar;
}

// What it registered must be exactly what its manifest provides, and nothing another loaded plugin registered.
bool PluginHost::accept(PluginRecord& record, detail::RecordingRegistrar& registrar) {
  const PluginManifest& manifest = *record.manifest;
  std::vector<ProvidedItem> registered;
  for (const auto& c : registrar.capabilities) registered.push_back({"capability", c.info.name, c.info.actuates, "", "", {}, {}});
  for (const auto& dr : registrar.drivers)
    registered.push_back({"driver", dr.info.protocol, dr.info.actuates, dr.info.interface, "", {}, {}});
  if (const auto differences = provides_differences(manifest.provides, registered); !differences.empty())
    return set_state(record, PluginState::ManifestMismatch, join(differences, "; "),
                     "make " + manifest.file.filename().string() +
                         " \"provides\" list exactly what the plugin registers, or rebuild the plugin"),
           false;
  for (const auto& other : records_) {
    if (other.get() == &record || other->state != PluginState::Loaded) continue;
    for (const auto& item : registered) {
      const bool taken = item.kind == "capability"
                             ? std::any_of(other->capabilities.begin(), other->capabilities.end(),
                                           [&](const RegisteredCapability& c) { return c.info.name == item.name; })
                             : std::any_of(other->drivers.begin(), other->drivers.end(),
                                           [&](const RegisteredDriver& dr) { return dr.info.protocol == item.name; });
      if (taken)
        return set_state(record, PluginState::RegistrationFailed,
                         item.kind + " '" + item.name + "' is already registered by plugin " + other->id,
                         "remove or disable one of the two plugins"),
               false;
    }
  }
  record.capabilities = std::move(registrar.capabilities);
  record.drivers = std::move(registrar.drivers);
  set_state(record, PluginState::Loaded, "", "");
  return true;
}

void PluginHost::reopen(std::string_view id) {
  PluginRecord* record = find(id);
  if (record == nullptr) return;
  // Served apart: its new version is for its next host processes, and rcand still maps none.
  const bool apart = record->state == PluginState::Loaded && record->library == nullptr;
  {
    std::lock_guard lock(mutex_);
    record->state = PluginState::InstalledNotEnabled;  // what it registered is free for its new version
    record->capabilities.clear();
    record->drivers.clear();
  }
  PluginRecord fresh;
  fresh.manifest_file = record->manifest_file;
  fresh.id = record->id;
  try {
    fresh.manifest = load_manifest(fresh.manifest_file);
    fresh.version = fresh.manifest->version;
  } catch (const std::exception& e) {
    set_state(fresh, PluginState::InvalidManifest, e.what(), "fix the manifest (format: manifests/manifest.schema.json)");
  }
  if (fresh.manifest && fresh.manifest->id != fresh.id)
    set_state(fresh, PluginState::InvalidManifest, "the manifest's id is now '" + fresh.manifest->id + "'",
              "a reload keeps a plugin's id; restart rcand to load it under another");
  else if (fresh.manifest && apart) serve_apart(fresh);
  else if (fresh.manifest) open_copy(fresh);
  std::lock_guard lock(mutex_);
  *record = std::move(fresh);
}

PluginHost::~PluginHost() {
  if (!reload_dir_.empty()) ::rmdir(reload_dir_.c_str());
}

void PluginHost::set_reload_parent(const fs::path& fallback) {
  reload_parent_ = fallback;
  const char* runtime = std::getenv("RUNTIME_DIRECTORY");  // systemd's RuntimeDirectory=; may list several
  const std::string first = runtime == nullptr ? "" : std::string(runtime, std::strcspn(runtime, ":"));
  struct statvfs mount {};
  if (!first.empty() && ::statvfs(first.c_str(), &mount) == 0 && (mount.f_flag & ST_NOEXEC) == 0) reload_parent_ = first;
}

int PluginHost::reopens_left(std::string_view id) const {
  const auto it = reopens_.find(id);
  return kMaxReopens - (it == reopens_.end() ? 0 : it->second);
}

fs::path PluginHost::private_copy(const fs::path& library, std::string& error) {
  if (reload_dir_.empty()) {
    std::string pattern = (reload_parent_ / "plugin-reload-XXXXXX").string();
    if (reload_parent_.empty() || ::mkdtemp(pattern.data()) == nullptr) {
      error = "cannot make a private directory in '" + reload_parent_.string() + "': " + std::strerror(errno);
      return {};
    }
    reload_dir_ = pattern;
  }
  const fs::path copy = reload_dir_ / (std::to_string(++copies_) + "-" + library.filename().string());
  const int in = ::open(library.c_str(), O_RDONLY | O_CLOEXEC);
  const int out = in < 0 ? -1 : ::open(copy.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  bool copied = out >= 0;
  std::array<char, 64 * 1024> buffer;
  while (copied) {
    const ssize_t n = ::read(in, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      copied = n == 0;
      break;
    }
    for (ssize_t done = 0, w = 0; copied && done < n; done += w) copied = (w = ::write(out, buffer.data() + done, n - done)) > 0;
  }
  error = copied ? "" : std::strerror(errno);
  if (out >= 0 && ::close(out) != 0 && copied) copied = false, error = std::strerror(errno);
  if (in >= 0) ::close(in);
  if (copied) return copy;
  if (out >= 0) ::unlink(copy.c_str());
  return {};
}

void PluginHost::open_copy(PluginRecord& record) {
  const fs::path original = record.manifest->library;
  if (reopens_left(record.id) <= 0)
    return set_state(record, PluginState::FailedToOpen,
                     "reloaded " + std::to_string(kMaxReopens) + " times: each reload keeps its old version mapped",
                     "restart rcand to reload it again");
  std::error_code ec;
  if (!fs::exists(original, ec)) return open(record);  // named as at startup: "library ... not found"
  std::string error;
  const fs::path copy = private_copy(original, error);
  if (copy.empty())
    return set_state(record, PluginState::FailedToOpen, "cannot copy " + original.string() + " to reload it: " + error,
                     "check the free space and permissions of " + reload_parent_.string());
  ++reopens_[record.id];  // one more image mapped for good, whatever open() makes of it
  record.manifest->library = copy;
  open(record);
  ::unlink(copy.c_str());  // mapped by now, or refused: the name is not needed any more
  record.manifest->library = original;
}

PluginRecord* PluginHost::find(std::string_view id) noexcept {
  for (const auto& record : records_)
    if (record->id == id) return record.get();
  return nullptr;
}

bool PluginHost::any_failed() const noexcept {
  return std::any_of(records_.begin(), records_.end(), [](const auto& r) { return is_failure(r->state); });
}

namespace {
std::string provides_text(const PluginRecord& record) {
  if (!record.manifest) return "-";
  std::vector<std::string> names;
  for (const auto& item : record.manifest->provides) names.push_back(item.kind == "driver" ? "driver:" + item.name : item.name);
  return join(names, ",");
}
}  // namespace

std::string PluginHost::format_table() const {
  std::lock_guard lock(mutex_);
  std::vector<std::array<std::string, 5>> rows{{"ID", "VERSION", "STATE", "PROVIDES", "REASON / HINT"}};
  for (const auto& r : records_) {
    std::string why = r->reason;
    if (!r->hint.empty()) why += (why.empty() ? "" : " / ") + ("hint: " + r->hint);
    rows.push_back({r->id, r->version.empty() ? "-" : r->version, std::string(to_string(r->state)), provides_text(*r),
                    why.empty() ? "-" : why});
  }
  std::array<std::size_t, 4> width{};
  for (const auto& row : rows)
    for (std::size_t c = 0; c < width.size(); ++c) width[c] = std::max(width[c], row[c].size());
  std::ostringstream out;
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < width.size(); ++c) out << row[c] << std::string(width[c] - row[c].size() + 2, ' ');
    out << row[4] << '\n';
  }
  return out.str();
}

namespace {

// "/usr/lib/rcand/plugins/libx.so: cannot open" -> "libx.so: cannot open": where the robot keeps its files is the
// operator's business, not every guest's.
std::string without_directories(const std::string& text) {
  std::string out;
  std::size_t i = 0;
  while (i < text.size()) {
    const bool starts_path = text[i] == '/' && (i == 0 || text[i - 1] == ' ' || text[i - 1] == '\'' || text[i - 1] == '(');
    if (!starts_path) {
      out.push_back(text[i++]);
      continue;
    }
    std::size_t end = i;
    while (end < text.size() && text[end] != ' ' && text[end] != '\'' && text[end] != ')' && text[end] != ',' &&
           !(text[end] == ':' && (end + 1 == text.size() || text[end + 1] == ' ')))
      ++end;
    const std::string path = text.substr(i, end - i);
    const auto slash = path.find_last_of('/');
    out += slash + 1 < path.size() ? path.substr(slash + 1) : path;
    i = end;
  }
  return out;
}

}  // namespace

json PluginHost::to_json(bool with_paths) const {
  std::lock_guard lock(mutex_);
  json out = json::array();
  for (const auto& r : records_) {
    json provided = json::array();
    if (r->manifest)
      for (const auto& item : r->manifest->provides) {
        json entry{{"kind", item.kind}, {"name", item.name}, {"actuates", item.actuates}};
        if (!item.interface.empty()) entry["interface"] = item.interface;
        provided.push_back(std::move(entry));
      }
    json item{{"id", r->id},
              {"version", r->version},
              {"state", to_string(r->state)},
              {"reason", with_paths ? r->reason : without_directories(r->reason)},
              {"hint", with_paths ? r->hint : without_directories(r->hint)},
              {"provides", std::move(provided)}};
    if (with_paths) {
      item["manifest"] = r->manifest_file.string();
      item["build_info"] = r->build_info;
    }
    out.push_back(std::move(item));
  }
  return out;
}

}  // namespace rcand::kernel
