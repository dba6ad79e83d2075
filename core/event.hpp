#pragma once
// The four FSG dynamic events: what the harness runs and what the driver's mission is.

#include <optional>
#include <string_view>

namespace conesim::core {

/// The four FSG dynamic events.
enum class EventType { kSkidpad, kAcceleration, kAutocross, kTrackdrive };

/// Event name as used on the command line and in scenarios: skidpad, acceleration, ...
std::string_view to_string(EventType e);

/// Parses an event name; nullopt when it is not one of the four.
std::optional<EventType> event_from_string(std::string_view name);

}  // namespace conesim::core
