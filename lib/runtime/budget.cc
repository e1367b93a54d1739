// DeriveBudget: the one place K_max comes from.
#include "runtime/budget.h"

#include <algorithm>
#include <cstdio>

#include "arena/arena.h"
#include "arena/frame_scratch.h"
#include "localization/frame_scratch_size.h"
#include "localization/localizer.h"
#include "memory/policy_kind.h"

namespace zm {

std::string FormatBytes(std::uint64_t bytes) {
  char buf[64];
  const double b = static_cast<double>(bytes);
  if (bytes >= 1000000000ULL) {
    std::snprintf(buf, sizeof buf, "%.2f GB (%.2f GiB)", b / 1e9, b / 1073741824.0);
  } else if (bytes >= 1000000ULL) {
    std::snprintf(buf, sizeof buf, "%.2f MB (%.2f MiB)", b / 1e6, b / 1048576.0);
  } else {
    std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  }
  return buf;
}

Result<std::uint64_t> MapShareBytes(const DeviceOptions& device, const ModelOptions& model,
                                    const MapOptions& map) {
  if (map.map_share_bytes != 0) return map.map_share_bytes;
  if (device.memory_bytes == 0) return std::uint64_t{0};
  const std::uint64_t model_bytes = model.weights_bytes + model.kv_cache_bytes;
  const std::uint64_t taken = device.os_reserve_bytes + model_bytes + map.headroom_bytes;
  if (taken >= device.memory_bytes) {
    return InvalidArgument("no map share left on " + device.name + ": OS reserve " +
                           FormatBytes(device.os_reserve_bytes) + " + model " +
                           FormatBytes(model_bytes) + " + headroom " +
                           FormatBytes(map.headroom_bytes) + " >= device memory " +
                           FormatBytes(device.memory_bytes) +
                           " (set map.map_share_bytes explicitly or shrink one of them)");
  }
  return device.memory_bytes - taken;
}

BudgetInputs BudgetInputsFor(const DeviceOptions& device, const ModelOptions& model,
                             const MapOptions& map, PolicyKind policy,
                             std::uint64_t largest_keyframe_bytes, std::uint64_t keyframe_count) {
  BudgetInputs in;
  in.device = device;
  in.model = model;
  in.map = map;
  in.largest_keyframe_bytes = largest_keyframe_bytes;
  in.keyframe_count = keyframe_count;
  in.bounded_policy = Traits(policy).bounded;
  in.unbounded_policy = !Traits(policy).has_budget;
  return in;
}

namespace {

// What the inverted index over `slots` arena slots reserves; 0 without a vocabulary.
std::uint64_t IndexBytes(const LocalizationInputs& l, std::uint64_t slots) {
  if (l.vocabulary_words == 0 || slots == 0) return 0;
  return VocabularyIndexBytes(l.vocabulary_words, static_cast<std::uint32_t>(slots),
                              l.word_features);
}

// The index over the arena's slots must be one the localizer can build (32-bit postings).
Status CheckIndex(const LocalizationInputs& l, std::uint32_t slots) {
  if (l.vocabulary_words == 0) return Status::Ok();
  return ValidateInvertedIndexOptions({.word_count = l.vocabulary_words,
                                       .max_keyframes = slots,
                                       .max_words_per_keyframe = l.word_features});
}

// The largest k <= limit whose slots and index fit `room` (0 when not even one does). The cost
// grows with k, so a bisection finds it.
std::uint64_t LargestFit(std::uint64_t room, std::uint64_t slot_bytes, std::uint64_t limit,
                         const LocalizationInputs& l) {
  const auto fits = [&](std::uint64_t k) { return k * slot_bytes + IndexBytes(l, k) <= room; };
  std::uint64_t lo = 0, hi = std::min(limit, room / slot_bytes);
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo + 1) / 2;
    if (fits(mid)) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  return lo;
}

}  // namespace

Result<Budget> DeriveBudget(const BudgetInputs& in) {
  if (in.keyframe_count == 0) return InvalidArgument("the map has no keyframes");
  if (in.keyframe_count > 0xFFFFFFFFull) {
    return OutOfRange("the map has " + std::to_string(in.keyframe_count) +
                      " keyframes; at most 4294967295 are supported");
  }
  Budget b;
  b.slot_bytes = in.map.slot_bytes != 0 ? in.map.slot_bytes : in.largest_keyframe_bytes;
  if (b.slot_bytes == 0) {
    return InvalidArgument("the slot size is unknown: map.slot_bytes is 0 and the map reports no "
                           "keyframe size");
  }
  if (b.slot_bytes < in.largest_keyframe_bytes) {
    return OutOfRange("map.slot_bytes " + std::to_string(b.slot_bytes) +
                      " is smaller than the largest keyframe (" +
                      std::to_string(in.largest_keyframe_bytes) + " bytes)");
  }
  const LocalizationInputs& loc = in.localization;
  if (loc.vocabulary_words != 0) {
    ZM_RETURN_IF_ERROR(CheckIndex(loc, 1));
    b.vocabulary_bytes = loc.vocabulary_bytes;
  }
  if (loc.image_width != 0 && loc.image_height != 0) {
    b.frame_scratch_bytes = FrameScratch::ReservedBytes(
        loc.scratch_bytes != 0 ? loc.scratch_bytes
                               : FrameScratchBytesFor(loc.image_width, loc.image_height));
  }
  const auto whole_map = static_cast<std::uint32_t>(in.keyframe_count);
  if (in.unbounded_policy) {
    b.k_max = whole_map;
    b.arena_slots = whole_map;
    b.bounded = false;
    b.arena_slot_bytes = ArenaSlotBytes(b.slot_bytes, /*release_to_os=*/true);
    ZM_RETURN_IF_ERROR(CheckIndex(loc, b.arena_slots));
    b.index_bytes = IndexBytes(loc, b.arena_slots);
    return b;
  }
  ZM_ASSIGN_OR_RETURN(b.map_share_bytes, MapShareBytes(in.device, in.model, in.map));
  std::uint64_t k = in.keyframe_count;
  if (in.map.memory_thr_keyframes != 0) k = std::min(k, in.map.memory_thr_keyframes);
  if (b.map_share_bytes != 0) {
    const std::uint64_t besides =
        in.map.overhead_bytes + b.vocabulary_bytes + b.frame_scratch_bytes;
    if (besides >= b.map_share_bytes) {
      return OutOfRange("map.overhead_bytes (" + FormatBytes(in.map.overhead_bytes) +
                        ") + vocabulary (" + FormatBytes(b.vocabulary_bytes) +
                        ") + frame scratch (" + FormatBytes(b.frame_scratch_bytes) +
                        ") leave nothing of the map share (" + FormatBytes(b.map_share_bytes) +
                        ") for keyframes");
    }
    b.keyframe_bytes = b.map_share_bytes - besides;
    const std::uint64_t fit = LargestFit(b.keyframe_bytes, b.slot_bytes, k, loc);
    if (fit == 0) {
      return OutOfRange("the keyframe budget " + FormatBytes(b.keyframe_bytes) +
                        " holds no keyframe slot of " + FormatBytes(b.slot_bytes) +
                        (loc.vocabulary_words != 0 ? " with its place in the inverted index" : ""));
    }
    k = fit;
  }
  b.k_max = static_cast<std::uint32_t>(k);
  b.bounded = in.bounded_policy;
  b.arena_slots = b.bounded ? b.k_max : whole_map;
  // A whole-map arena (basic, unbounded) gives its slots' pages back: page-aligned slots.
  b.arena_slot_bytes = ArenaSlotBytes(b.slot_bytes, /*release_to_os=*/!b.bounded);
  ZM_RETURN_IF_ERROR(CheckIndex(loc, b.arena_slots));
  b.index_bytes = IndexBytes(loc, b.arena_slots);
  return b;
}

}  // namespace zm
