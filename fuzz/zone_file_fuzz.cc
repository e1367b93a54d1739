// libFuzzer target: the zone-file parser (GeoJSON and keyframe lists, lib/zones/zone_set.h).
// Any input must give a ZoneSet or an error Status; never a crash, a hang or a sanitizer report.
// A parsed set must satisfy ZoneSet's invariants (dense ids, unique names, polygons >= 3).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "zones/zone_set.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto zones = zm::ParseZoneJson(text, "fuzz.json");
  if (!zones.ok()) {
    if (zones.status().message().empty()) std::abort();
    return 0;
  }
  for (std::size_t i = 0; i < zones->size(); ++i) {
    const zm::Zone& z = zones->zones()[i];
    if (z.id.value != static_cast<std::int32_t>(i) || z.name.empty()) std::abort();
    if (!zones->has_keyframe_lists() && z.polygon.size() < 3) std::abort();
    if (zones->Find(z.name) != z.id) std::abort();
  }
  // Writing back must not crash either (polygon sets only).
  if (!zones->has_keyframe_lists()) (void)zm::ToGeoJsonText(*zones);
  return 0;
}
