#include "core/event.hpp"

#include <array>
#include <utility>

namespace conesim::core {

namespace {
constexpr std::array<std::pair<EventType, std::string_view>, 4> kEventNames{{
    {EventType::kSkidpad, "skidpad"},
    {EventType::kAcceleration, "acceleration"},
    {EventType::kAutocross, "autocross"},
    {EventType::kTrackdrive, "trackdrive"},
}};
}  // namespace

std::string_view to_string(EventType e) {
  for (const auto& [ev, name] : kEventNames)
    if (ev == e) return name;
  return "trackdrive";
}

std::optional<EventType> event_from_string(std::string_view name) {
  for (const auto& [ev, n] : kEventNames)
    if (n == name) return ev;
  return std::nullopt;
}

}  // namespace conesim::core
