#pragma once
// The entry point of a plug-in library: one C function, `conesim_plugin_entry`, returning a
// PluginInfo whose first field is the ABI version the plug-in was built against. conesim reads
// that field first and refuses a plug-in of another ABI before it touches anything else.
//
//   class MyDriver : public conesim::sdk::Driver { ... };
//   CONESIM_PLUGIN_DRIVER("my_driver", MyDriver)
//
// A plug-in class needs a constructor (const RunInfo&, const Config&). One library may offer
// several kinds: use CONESIM_PLUGIN(name, perception_class, slam_class, driver_class) with
// `void` for the kinds it does not offer.

#include <type_traits>

#include "conesim/sdk/config.hpp"
#include "conesim/sdk/interfaces.hpp"
#include "conesim/sdk/version.hpp"

namespace conesim::sdk {

/// What a plug-in library offers. Factories are null for the kinds it does not offer. A
/// factory may throw std::exception (e.g. from Config's readers): conesim refuses the scenario
/// with the message, naming the plug-in (exit status 2).
struct PluginInfo {
  /// kAbiVersion of the headers the plug-in was built with. First field, never moved.
  uint32_t abi_version = 0;
  /// kSdkVersion of those headers.
  const char* sdk_version = "";
  /// The plug-in's name in outputs (metrics.json, DNF reasons): letters, digits, '_' and '-'.
  const char* name = "";
  Perception* (*create_perception)(const RunInfo&, const Config&) = nullptr;
  Slam* (*create_slam)(const RunInfo&, const Config&) = nullptr;
  Driver* (*create_driver)(const RunInfo&, const Config&) = nullptr;
};

/// The entry point's symbol name.
inline constexpr const char* kEntryPointSymbol = "conesim_plugin_entry";

namespace detail {
// a factory for T as the interface I, or null when T is void
template <typename I, typename T>
constexpr I* (*factory())(const RunInfo&, const Config&) {
  if constexpr (std::is_void_v<T>) {
    return nullptr;
  } else {
    static_assert(std::is_base_of_v<I, T>, "a plug-in class must derive from its interface");
    return [](const RunInfo& run, const Config& config) -> I* { return new T(run, config); };
  }
}
}  // namespace detail

}  // namespace conesim::sdk

/// Defines the entry point of a plug-in offering the given classes (void for none).
#define CONESIM_PLUGIN(NAME, PERCEPTION, SLAM, DRIVER)                                \
  extern "C" __attribute__((visibility("default"))) const ::conesim::sdk::PluginInfo* \
  conesim_plugin_entry() {                                                            \
    static const ::conesim::sdk::PluginInfo info{                                     \
        ::conesim::sdk::kAbiVersion,                                                  \
        ::conesim::sdk::kSdkVersion,                                                  \
        NAME,                                                                         \
        ::conesim::sdk::detail::factory<::conesim::sdk::Perception, PERCEPTION>(),    \
        ::conesim::sdk::detail::factory<::conesim::sdk::Slam, SLAM>(),                \
        ::conesim::sdk::detail::factory<::conesim::sdk::Driver, DRIVER>()};           \
    return &info;                                                                     \
  }

/// A plug-in offering one Driver.
#define CONESIM_PLUGIN_DRIVER(NAME, CLASS) CONESIM_PLUGIN(NAME, void, void, CLASS)
/// A plug-in offering one Slam.
#define CONESIM_PLUGIN_SLAM(NAME, CLASS) CONESIM_PLUGIN(NAME, void, CLASS, void)
/// A plug-in offering one Perception.
#define CONESIM_PLUGIN_PERCEPTION(NAME, CLASS) CONESIM_PLUGIN(NAME, CLASS, void, void)
