// Strong ids: keyframe, zone and slot numbers are different types, so one cannot be passed
// where another is expected (docs/style.md §3). Trivially copyable, hashable, ordered.
//
// KeyframeId, ZoneId (with kNoZone) and LinkKind are the public API's (include/zonemap/types.h):
// one definition each, so the core and a host share them without conversion. SlotIndex is the
// arena's, which knows nothing of ours. StrongId makes the ids private to one module (WordId).
#pragma once

#include <compare>
#include <cstdint>
#include <functional>

#include "arena/arena.h"
#include "zonemap/types.h"

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

// Keyframe ids are RTAB-Map node ids when imported (positive, 32-bit there); 64-bit here. 0 means
// "none" where an id is optional.
using KeyframeId = zonemap::KeyframeId;
// Zone ids are dense 0..N-1 within a map, so they index arrays directly; default kNoZone.
using ZoneId = zonemap::ZoneId;
using zonemap::kNoZone;
// RTAB-Map's Link.type values, kept as-is on import.
using LinkKind = zonemap::LinkKind;

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
