// The plugins a fake host (rcand/sdk/testing/fake_host.hpp) loaded and what they registered, checked as the kernel
// checks them: the descriptor (magic, size, ABI major and minor, id, version), then one call of the register
// function, and with a manifest its id, version and "provides" against the registrations and a well-formed settings
// schema. A plugin refused at load leaves nothing behind.
#pragma once

#include <nlohmann/json.hpp>

#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>

#include "rcand/sdk/abi.h"
#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/contract/settings.hpp"
#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/registrar.hpp"

namespace rcand::sdk::testing {

// Misuse of the host, or a plugin instance that failed to construct or start (the kernel would record it
// failed; a test wants to know at once).
class HostError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// The plugin was refused at load: bad descriptor, incompatible ABI, manifest mismatch, registration failed.
class LoadError : public HostError {
 public:
  using HostError::HostError;
};

class FakePluginRegistry {
 public:
  struct CapabilityRegistration {
    CapabilityInfo info;
    CapabilityFactory factory;
    std::string plugin_id;
  };
  struct DriverRegistration {
    DriverInfo info;
    DriverFactory factory;
    std::string plugin_id;
  };

  // Throws LoadError with the reason. `manifest`: null to load without one (no settings schema is then checked).
  void load(rcand_plugin_entry_fn entry, const nlohmann::json* manifest) {
    if (!entry) throw LoadError("failed-to-open: the entry function is null");
    const rcand_plugin_descriptor* d = entry();
    if (!d) throw LoadError("failed-to-open: the entry function returned no descriptor");
    if (d->magic != RCAND_DESCRIPTOR_MAGIC) throw LoadError("incompatible-abi: bad descriptor magic (not an rcand plugin)");
    if (d->struct_size > sizeof(rcand_plugin_descriptor))
      throw LoadError("incompatible-abi: descriptor is " + std::to_string(d->struct_size) + " bytes, larger than this host's " +
                      std::to_string(sizeof(rcand_plugin_descriptor)) + " (built against a newer SDK)");
    if (d->struct_size < sizeof(rcand_plugin_descriptor))  // the 1.0 layout is the current one
      throw LoadError("incompatible-abi: descriptor is " + std::to_string(d->struct_size) +
                      " bytes, smaller than the ABI 1.0 layout");
    if (d->abi_major != RCAND_ABI_MAJOR)
      throw LoadError("incompatible-abi: built for ABI " + std::to_string(d->abi_major) + ", host speaks " +
                      std::to_string(RCAND_ABI_MAJOR));
    if (d->abi_minor > RCAND_ABI_MINOR)
      throw LoadError("incompatible-abi: built for ABI " + std::to_string(d->abi_major) + "." + std::to_string(d->abi_minor) +
                      ", newer than the host's " + std::to_string(RCAND_ABI_MAJOR) + "." + std::to_string(RCAND_ABI_MINOR));
    if (!d->plugin_id || !*d->plugin_id) throw LoadError("incompatible-abi: the descriptor has no plugin id");
    if (!d->version || !*d->version) throw LoadError("incompatible-abi: the descriptor has no version");
    if (!d->register_plugin) throw LoadError("incompatible-abi: the descriptor has no register function");
    const std::string id = d->plugin_id;
    if (loaded_.count(id)) throw LoadError("duplicate plugin id '" + id + "'");
    if (manifest) check_manifest_identity(*manifest, id, d->version);
    if (manifest) {  // the kernel's manifest check, from the same contract
      try {
        if (manifest->contains("config")) contract::check_settings_schema(manifest->at("config"), "config.");
        const auto provides = manifest->value("provides", nlohmann::json::array());
        for (std::size_t i = 0; i < provides.size(); ++i)
          if (provides[i].is_object()) contract::check_provided_item(provides[i], "provides[" + std::to_string(i) + "]");
      } catch (const contract::SettingsError& e) {
        throw LoadError(std::string("invalid-manifest: ") + e.what());
      }
    }

    Recorder recorder(*this, id);
    try {
      d->register_plugin(reinterpret_cast<rcand_registrar*>(static_cast<Registrar*>(&recorder)));
    } catch (const std::exception& e) {
      throw LoadError("registration-failed: " + id + ": " + e.what());
    } catch (...) {
      throw LoadError("registration-failed: " + id + ": unknown exception");
    }
    recorder.closed = true;
    if (manifest) check_provides(*manifest, id, recorder);

    loaded_.insert(id);
    if (manifest) manifests_[id] = *manifest;  // its settings schemas: none means the plugin takes no settings
    for (auto& [name, reg] : recorder.capabilities) capabilities_.emplace(name, std::move(reg));
    for (auto& [protocol, reg] : recorder.drivers) drivers_.emplace(protocol, std::move(reg));
  }

  const CapabilityRegistration* capability(std::string_view name) const {
    const auto it = capabilities_.find(name);
    return it == capabilities_.end() ? nullptr : &it->second;
  }
  const DriverRegistration* driver(std::string_view protocol) const {
    const auto it = drivers_.find(protocol);
    return it == drivers_.end() ? nullptr : &it->second;
  }
  // The manifest `plugin_id` was loaded with; null when it was loaded without one.
  const nlohmann::json* manifest(const std::string& plugin_id) const {
    const auto it = manifests_.find(plugin_id);
    return it == manifests_.end() ? nullptr : &it->second;
  }
  // " (known: a, b)" or " (none loaded)", for an error that names what is missing.
  std::string known_capabilities() const { return known(capabilities_); }
  std::string known_drivers() const { return known(drivers_); }

 private:
  // Stages what one register function adds; the host keeps it only if the whole registration succeeds.
  class Recorder final : public Registrar {
   public:
    Recorder(const FakePluginRegistry& registry, std::string plugin_id) : registry_(registry), plugin_id_(std::move(plugin_id)) {}
    void add_capability(CapabilityInfo info, CapabilityFactory factory) override {
      if (closed) throw std::logic_error("add_capability called outside the register function");
      if (info.name.empty()) throw std::invalid_argument("add_capability: empty capability name");
      if (!factory) throw std::invalid_argument("add_capability(" + info.name + "): null factory");
      if (capabilities.count(info.name) || registry_.capabilities_.count(info.name))
        throw std::invalid_argument("capability '" + info.name + "' is registered twice");
      const std::string name = info.name;
      capabilities.emplace(name, CapabilityRegistration{std::move(info), std::move(factory), plugin_id_});
    }
    void add_driver(DriverInfo info, DriverFactory factory) override {
      if (closed) throw std::logic_error("add_driver called outside the register function");
      if (info.protocol.empty()) throw std::invalid_argument("add_driver: empty protocol");
      if (!factory) throw std::invalid_argument("add_driver(" + info.protocol + "): null factory");
      if (info.actuates && info.interface.empty())
        throw std::invalid_argument("add_driver(" + info.protocol + "): an actuating driver must name its interface");
      if (drivers.count(info.protocol) || registry_.drivers_.count(info.protocol))
        throw std::invalid_argument("driver protocol '" + info.protocol + "' is registered twice");
      const std::string protocol = info.protocol;
      drivers.emplace(protocol, DriverRegistration{std::move(info), std::move(factory), plugin_id_});
    }

    bool closed = false;
    std::map<std::string, CapabilityRegistration, std::less<>> capabilities;
    std::map<std::string, DriverRegistration, std::less<>> drivers;

   private:
    const FakePluginRegistry& registry_;
    std::string plugin_id_;
  };

  static void check_manifest_identity(const nlohmann::json& m, const std::string& id, const std::string& version) {
    if (!m.is_object()) throw LoadError("manifest-mismatch: the manifest is not a JSON object");
    if (m.value("id", std::string()) != id)
      throw LoadError("manifest-mismatch: descriptor id '" + id + "' != manifest id '" + m.value("id", std::string()) + "'");
    if (m.value("version", std::string()) != version)
      throw LoadError("manifest-mismatch: descriptor version '" + version + "' != manifest version '" +
                      m.value("version", std::string()) + "'");
  }

  // Registered items must equal the manifest's "provides" (kind, name, actuates, interface), as a set.
  static void check_provides(const nlohmann::json& m, const std::string& id, const Recorder& r) {
    using Item = std::tuple<std::string, std::string, bool, std::string>;
    std::set<Item> declared, registered;
    const auto provides = m.find("provides");
    if (provides == m.end() || !provides->is_array()) throw LoadError("manifest-mismatch: " + id + ": no provides[] array");
    for (const auto& p : *provides) {
      if (!p.is_object() || !p.contains("kind") || !p.contains("name"))
        throw LoadError("manifest-mismatch: " + id + ": provides[] items need kind and name");
      declared.emplace(p.value("kind", std::string()), p.value("name", std::string()), p.value("actuates", false),
                       p.value("interface", std::string()));
    }
    for (const auto& [name, reg] : r.capabilities) registered.emplace("capability", name, reg.info.actuates, "");
    for (const auto& [protocol, reg] : r.drivers) registered.emplace("driver", protocol, reg.info.actuates, reg.info.interface);
    if (declared != registered) {
      auto describe = [](const std::set<Item>& items) {
        std::string out;
        for (const auto& [kind, name, actuates, interface] : items)
          out += (out.empty() ? "" : ", ") + kind + " " + name + (actuates ? " (actuates" : " (") +
                 (interface.empty() ? "" : " " + interface) + ")";
        return out.empty() ? std::string("nothing") : out;
      };
      throw LoadError("manifest-mismatch: " + id + " registered " + describe(registered) + " but its manifest provides " +
                      describe(declared));
    }
  }

  template <class Map> static std::string known(const Map& map) {
    std::string out;
    for (const auto& [name, reg] : map) out += (out.empty() ? "" : ", ") + name;
    return out.empty() ? " (none loaded)" : " (known: " + out + ")";
  }

  std::set<std::string> loaded_;
  std::map<std::string, nlohmann::json> manifests_;
  std::map<std::string, CapabilityRegistration, std::less<>> capabilities_;
  std::map<std::string, DriverRegistration, std::less<>> drivers_;
};

}  // namespace rcand::sdk::testing
