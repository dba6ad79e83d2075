// A plug-in built against another SDK ABI (its entry point reports ABI 999): conesim must
// refuse it before reading anything else (tests/app/sdk_test.sh).

#include <conesim/sdk/plugin.hpp>

extern "C" __attribute__((visibility("default"))) const conesim::sdk::PluginInfo*
conesim_plugin_entry() {
  static const conesim::sdk::PluginInfo info{999,     "9.9.9", "from_the_future",
                                             nullptr, nullptr, nullptr};
  return &info;
}
