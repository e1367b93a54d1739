#include "mapdb/map_scan.h"

#include <cmath>
#include <optional>
#include <string>
#include <variant>

#include "arena/arena.h"

namespace zm {
namespace {

// Remembers the one slot a LoadKeyframes call filled.
class OneSlotSink final : public LoadSink {
 public:
  bool Wants(KeyframeId /*id*/) override { return true; }
  void Loaded(KeyframeId /*id*/, SlotIndex slot, std::uint32_t /*payload_bytes*/) override {
    slot_ = slot;
  }
  std::optional<SlotIndex> Take() {
    auto s = slot_;
    slot_.reset();
    return s;
  }

 private:
  std::optional<SlotIndex> slot_;
};

}  // namespace

Status ScanKeyframes(MapDb& map, std::span<const KeyframeMeta> keyframes,
                     const KeyframeVisitor& visit) {
  if (keyframes.empty()) return Status::Ok();
  ArenaConfig config;
  config.memory_thr_keyframes = 1;
  config.slot_bytes = std::max<std::uint64_t>(map.metadata().largest_payload_bytes, 64);
  auto created = Arena::Create(config);
  if (const auto* err = std::get_if<ArenaError>(&created)) {
    return ResourceExhausted("scanning the keyframes of the map: " + err->message);
  }
  Arena& arena = std::get<Arena>(created);
  OneSlotSink sink;
  for (const KeyframeMeta& meta : keyframes) {
    const KeyframeId id = meta.id;
    ZM_RETURN_IF_ERROR(map.LoadKeyframes(std::span<const KeyframeId>(&id, 1), arena, sink).status());
    const std::optional<SlotIndex> slot = sink.Take();
    if (!slot) return Internal("keyframe " + std::to_string(id.value) + " loaded into no slot");
    // Validated (and its checksum verified) as it landed: no second check here.
    auto view = DecodePayload(arena.Slot(*slot), DecodeOptions{.verify_crc = false},
                              /*blob_is_slot=*/true);
    Status st = view.ok() ? visit(meta, *view) : view.status();
    arena.Release(*slot);
    ZM_RETURN_IF_ERROR(st);
  }
  return Status::Ok();
}

KeyframeContent CountKeyframeContent(const KeyframeView& view) {
  KeyframeContent c;
  c.features = view.feature_count;
  if (view.points != nullptr) {
    for (std::uint32_t i = 0; i < view.feature_count; ++i) {
      const float* p = view.points + 3 * std::size_t{i};
      if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) ++c.points3d;
    }
  }
  switch (view.dense_format) {
    case DenseFormat::kJpegColourRvlDepth:
    case DenseFormat::kPngDepthAndJpegColour:
      c.has_colour = true;
      c.has_depth = true;
      break;
    case DenseFormat::kJpegColour:
      c.has_colour = true;
      break;
    case DenseFormat::kPngDepth16:
    case DenseFormat::kRvlDepth16:
      c.has_depth = true;
      break;
    case DenseFormat::kNone:
    case DenseFormat::kOpaque:
      break;
  }
  return c;
}

}  // namespace zm
