#pragma once
// A plug-in's configuration: its YAML block from the scenario, flattened to key/value text.
// Header-only: the readers run in the plug-in, so nothing of them crosses the boundary.

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "conesim/sdk/types.hpp"

namespace conesim::sdk {

/// The `config:` block a scenario gives a plug-in. Nested keys are joined with dots
/// ("lookahead.min_m"), list items by index ("gains.0"). The readers throw
/// std::invalid_argument naming the key and what was expected; thrown from a plug-in's
/// factory it refuses the scenario (exit status 2) with that message.
class Config {
 public:
  /// A view of the entries and the block's YAML text (both owned by conesim, valid while the
  /// factory runs: copy what you keep).
  Config(Span<ConfigEntry> entries, const char* yaml) : entries_(entries), yaml_(yaml) {}

  /// Every entry, in the order of the file.
  Span<ConfigEntry> entries() const { return entries_; }
  /// The block as YAML text ("{}" when the scenario gives none).
  const char* yaml() const { return yaml_ ? yaml_ : "{}"; }

  /// True when the block has this key.
  bool has(const char* key) const { return find(key) != nullptr; }

  /// The text of a key, or `fallback` when absent.
  std::string text(const char* key, const std::string& fallback) const {
    const char* v = find(key);
    return v ? std::string(v) : fallback;
  }

  /// A finite number, or `fallback` when absent.
  double number(const char* key, double fallback) const {
    const char* v = find(key);
    if (!v) return fallback;
    char* end = nullptr;
    const double x = std::strtod(v, &end);
    if (end == v || *end != '\0' || !std::isfinite(x))
      throw std::invalid_argument(std::string(key) + ": expected a finite number, got '" + v + "'");
    return x;
  }

  /// true or false, or `fallback` when absent.
  bool boolean(const char* key, bool fallback) const {
    const char* v = find(key);
    if (!v) return fallback;
    const std::string s(v);
    if (s == "true") return true;
    if (s == "false") return false;
    throw std::invalid_argument(std::string(key) + ": expected true or false, got '" + s + "'");
  }

  /// Throws std::invalid_argument for the first key not among `known` (a null-terminated list
  /// of top-level keys), naming it and the keys that are known.
  void require_known(const char* const* known) const {
    for (const ConfigEntry& e : entries_) {
      const std::string top = std::string(e.key).substr(0, std::string(e.key).find('.'));
      bool ok = false;
      std::string list;
      for (const char* const* k = known; *k; ++k) {
        ok = ok || top == *k;
        list += (list.empty() ? "" : ", ") + std::string(*k);
      }
      if (!ok) throw std::invalid_argument(top + ": unknown key (known: " + list + ")");
    }
  }

 private:
  const char* find(const char* key) const {
    for (const ConfigEntry& e : entries_)
      if (std::strcmp(e.key, key) == 0) return e.value;
    return nullptr;
  }

  Span<ConfigEntry> entries_;
  const char* yaml_ = nullptr;
};

}  // namespace conesim::sdk
