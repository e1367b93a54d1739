// zonemap public API: the small value types every call uses.
//
// Strong ids (a keyframe id cannot be passed where a zone id is expected) and a pose as seven
// doubles in TUM order. Why not Eigen here (docs/api.md): the library is compiled once with its
// own flags, while the host compiles these headers with its own Eigen version and its own
// vectorisation and alignment settings; Eigen's fixed-size types change layout with those
// (EIGEN_MAX_ALIGN_BYTES, -march), so passing them across a prebuilt library's boundary is an
// ABI hazard, and RTAB-Map, ROS and PCL hosts each convert from their own pose type anyway. Seven
// doubles are what TUM files and zonemapd's line protocol carry already.
//
// One definition: the library's core uses these very types (lib/common/ids.h aliases them), so
// an id or a link kind crosses the API unconverted.
//
// Header-only, standard library only; trivially copyable; no allocation.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <functional>

namespace zonemap {

// A keyframe's id in the host's own numbering (RTAB-Map node ids, say). Any value but 0, which
// means "none" where an id is optional.
struct KeyframeId {
  std::int64_t value = 0;
  friend constexpr bool operator==(KeyframeId, KeyframeId) = default;
  friend constexpr auto operator<=>(KeyframeId, KeyframeId) = default;
};

// A zone's id: dense, 0..zone_count()-1, in the order the zones were given (or read from the
// zone file). kNoZone = outside every zone / unknown.
struct ZoneId {
  std::int32_t value = -1;
  friend constexpr bool operator==(ZoneId, ZoneId) = default;
  friend constexpr auto operator<=>(ZoneId, ZoneId) = default;
};
inline constexpr ZoneId kNoZone{-1};

// Link kinds between keyframes, numbered as RTAB-Map's Link::Type (and stored so in zonemap's
// map database), so an RTAB-Map host can cast.
enum class LinkKind : std::int32_t {
  kNeighbor = 0,
  kGlobalClosure = 1,
  kLocalSpaceClosure = 2,
  kLocalTimeClosure = 3,
  kUserClosure = 4,
  kVirtualClosure = 5,
  kNeighborMerged = 6,
  kPosePrior = 7,
  kLandmark = 8,
  kGravity = 9,
};

// A rigid-body pose in the map frame: metres, and a unit quaternion with w last (TUM order,
// as in trajectory files and zonemapd's line protocol). A quaternion within the profile's
// [input] quaternion_tolerance of unit norm (0.01 by default) is normalised by zonemap; anything
// else, or a non-finite number, is rejected (zonemapd's input gate; docs/api.md).
struct Pose {
  double x = 0.0, y = 0.0, z = 0.0;
  double qx = 0.0, qy = 0.0, qz = 0.0, qw = 1.0;
};

// "MAJOR.MINOR.PATCH" of the library linked in.
[[nodiscard]] const char* Version();

}  // namespace zonemap

template <>
struct std::hash<zonemap::KeyframeId> {
  std::size_t operator()(zonemap::KeyframeId id) const noexcept {
    return std::hash<std::int64_t>{}(id.value);
  }
};
template <>
struct std::hash<zonemap::ZoneId> {
  std::size_t operator()(zonemap::ZoneId id) const noexcept {
    return std::hash<std::int32_t>{}(id.value);
  }
};
