// Strong ids: keyframe, zone and slot numbers are different types, so one cannot be passed
// where another is expected (docs/style.md §3). Trivially copyable, hashable, ordered.
#pragma once

#include <compare>
#include <cstdint>
#include <functional>

#include "arena/arena.h"  // SlotIndex is defined by the arena, which knows nothing of ours.

namespace zm {

template <class Tag, class Rep>
struct StrongId {
  using rep_type = Rep;
  Rep value{};
  constexpr StrongId() = default;
  constexpr explicit StrongId(Rep v) : value(v) {}
  friend constexpr bool operator==(StrongId, StrongId) = default;
  friend constexpr auto operator<=>(StrongId, StrongId) = default;
};

struct KeyframeIdTag {};
struct ZoneIdTag {};

// Keyframe ids are RTAB-Map node ids when imported (positive, 32-bit there); 64-bit here.
using KeyframeId = StrongId<KeyframeIdTag, std::int64_t>;
// Zone ids are dense 0..N-1 within a map, so they index arrays directly.
using ZoneId = StrongId<ZoneIdTag, std::int32_t>;
inline constexpr ZoneId kNoZone{-1};

}  // namespace zm

template <class Tag, class Rep>
struct std::hash<zm::StrongId<Tag, Rep>> {
  std::size_t operator()(zm::StrongId<Tag, Rep> id) const noexcept {
    return std::hash<Rep>{}(id.value);
  }
};
template <>
struct std::hash<zm::SlotIndex> {
  std::size_t operator()(zm::SlotIndex id) const noexcept {
    return std::hash<std::uint32_t>{}(id.value);
  }
};
