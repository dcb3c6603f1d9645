// Typed services between plugins (SDK ABI 1.2). A plugin offers an object implementing a service interface; any
// plugin (and rcand's in-tree services) finds it by the interface's id. One mechanism for every such interface, so a
// new one (nav's pose, vision's obstacles, a vendor's arm planner) needs no new PluginContext method:
//
//   void start() override { rcand::sdk::offer<rcand::sdk::PoseSource>(ctx_, *this); }          // the provider
//   if (const auto* pose = rcand::sdk::find<rcand::sdk::PoseSource>(ctx_)) use(pose->read());  // a user, at use time
//
// A service interface is an abstract class with `static constexpr std::string_view kServiceId`, written
// "<owner>.<name>/<version>": "rcand.pose_source/1", "com.acme.arm_planner/1". The id stands for the class's exact
// C++ shape: any change to the class takes a new version, so a finder never gets an object of a shape it was not
// compiled for. Hosts compare ids only; the object crosses as `const void*` and the typed helpers below cast it back
// to the interface named by the same id. No RTTI is involved, so this works between libraries dlopen'ed with
// RTLD_LOCAL (where typeid and dynamic_cast may not agree on a type).
//
// The rules, the same in rcand and in the fake host (testing/fake_host.hpp):
// - One provider per id. Offering an id that is already offered is refused: logged, and offer() returns false.
// - The offering instance owns the object. It stays valid until the instance is destroyed (make it a member of the
//   capability or driver, or the instance itself); the host withdraws an instance's offers before its shutdown().
//   A failed instance's offers are no longer found.
// - find() returns nullptr when nothing offers the id: not configured, not started yet, failed or stopped. Find at
//   use time and do not keep the pointer past the call, so the order in which plugins start does not matter.
// - offer() and find(): any thread, never block, never throw.
// - A service's methods are called on the caller's thread, with no kernel trampoline in between: they are const,
//   thread-safe, noexcept and must not block (a brief lock at most).
#pragma once

#include <concepts>
#include <string_view>
#include <type_traits>

namespace rcand::sdk {

template <class T>
concept ServiceInterface = std::is_class_v<T> && requires {
  { T::kServiceId } -> std::convertible_to<std::string_view>;
};

// The object offered as T, or nullptr. `host` is a PluginContext, or anything with the same `service(id)` call (the
// fake host, rcand's directory for its in-tree services).
template <ServiceInterface T, class Host> const T* find(const Host& host) noexcept {
  return static_cast<const T*>(host.service(T::kServiceId));
}

// Offers `service` as T. T is always written out (offer<PoseSource>(ctx, *this)): it is never deduced from the
// object, so an object implementing several interfaces is converted to the right one before it crosses as void*.
template <ServiceInterface T, class Host> bool offer(Host& host, const std::type_identity_t<T>& service) noexcept {
  return host.offer_service(T::kServiceId, static_cast<const void*>(&service));
}

}  // namespace rcand::sdk
