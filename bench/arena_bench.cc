// Acquire + release of one keyframe slot: the arena against malloc/free and mimalloc, for the
// slot sizes keyframes have (features only ~16 KiB, RGB-D ~64-256 KiB). The allocators are
// asked for the same size and the memory is touched once, as a zone load would.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <cstring>
#include <variant>

#include "arena/arena.h"
#ifdef ZM_HAVE_MIMALLOC
#include <mimalloc.h>
#endif

namespace {

constexpr int kBatch = 64;  // a small zone

void BM_ArenaAcquireRelease(benchmark::State& state) {
  const auto bytes = static_cast<std::uint64_t>(state.range(0));
  auto created = zm::Arena::Create({.memory_thr_keyframes = kBatch, .budget_bytes = 0,
                                    .slot_bytes = bytes, .lock = false, .prefault = true});
  auto& arena = std::get<zm::Arena>(created);
  zm::SlotIndex held[kBatch];
  for (auto _ : state) {
    for (int i = 0; i < kBatch; ++i) {
      held[i] = *arena.TryAcquire();
      arena.Slot(held[i])[0] = std::byte{1};
    }
    for (int i = 0; i < kBatch; ++i) arena.Release(held[i]);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}

void BM_MallocFree(benchmark::State& state) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  void* held[kBatch];
  for (auto _ : state) {
    for (int i = 0; i < kBatch; ++i) {
      held[i] = std::malloc(bytes);
      static_cast<char*>(held[i])[0] = 1;
    }
    for (int i = 0; i < kBatch; ++i) std::free(held[i]);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}

#ifdef ZM_HAVE_MIMALLOC
void BM_MimallocFree(benchmark::State& state) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  void* held[kBatch];
  for (auto _ : state) {
    for (int i = 0; i < kBatch; ++i) {
      held[i] = mi_malloc(bytes);
      static_cast<char*>(held[i])[0] = 1;
    }
    for (int i = 0; i < kBatch; ++i) mi_free(held[i]);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}
BENCHMARK(BM_MimallocFree)->Arg(16 << 10)->Arg(64 << 10)->Arg(256 << 10);
#endif

BENCHMARK(BM_ArenaAcquireRelease)->Arg(16 << 10)->Arg(64 << 10)->Arg(256 << 10);
BENCHMARK(BM_MallocFree)->Arg(16 << 10)->Arg(64 << 10)->Arg(256 << 10);

}  // namespace

BENCHMARK_MAIN();
