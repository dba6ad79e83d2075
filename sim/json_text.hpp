#pragma once
// JSON text of what conesim writes. Strings in it may come from a user's files: a file name or a
// key in another encoding (Latin-1 "Großer.yaml") is not valid UTF-8, and nlohmann's dump()
// throws on it. Here its bad bytes become U+FFFD instead, so a run still writes its results.

#include <nlohmann/json.hpp>
#include <string>

namespace conesim::sim {

/// j as text (indent < 0: one line), invalid UTF-8 in its strings replaced by U+FFFD.
inline std::string json_text(const nlohmann::json& j, int indent = -1) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace conesim::sim
