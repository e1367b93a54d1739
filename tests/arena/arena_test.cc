// The arena's contract: capacity arithmetic, refusal when full, disjoint slots, reuse,
// high-water mark, no heap traffic on acquire/release, clear errors for bad sizes, and memory the
// kernel sees (pre-faulted reservations; slots given back to the kernel with release_to_os).
#include "arena/arena.h"

#include <sys/mman.h>
#include <unistd.h>

#include <doctest/doctest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <set>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

Arena MakeArena(ArenaConfig c) {
  auto r = Arena::Create(c);
  REQUIRE(std::holds_alternative<Arena>(r));
  return std::move(std::get<Arena>(r));
}

ArenaError MakeError(ArenaConfig c) {
  auto r = Arena::Create(c);
  REQUIRE(std::holds_alternative<ArenaError>(r));
  return std::get<ArenaError>(r);
}

std::uint64_t PageBytes() { return static_cast<std::uint64_t>(sysconf(_SC_PAGE_SIZE)); }

// Bytes of `s` the kernel holds resident (mincore), whatever this process's other memory does.
std::uint64_t ResidentBytes(std::span<const std::byte> s) {
  const std::uint64_t page = PageBytes();
  const auto addr = reinterpret_cast<std::uintptr_t>(s.data());
  const std::uintptr_t first = addr / page * page;
  const std::uint64_t len = addr + s.size() - first;
  std::vector<unsigned char> vec((len + page - 1) / page);
  REQUIRE(mincore(reinterpret_cast<void*>(first), len, vec.data()) == 0);
  return static_cast<std::uint64_t>(std::count_if(vec.begin(), vec.end(),
                                                  [](unsigned char v) { return (v & 1U) != 0; })) *
         page;
}

// This process's resident set as the kernel counts it (/proc/self/statm, second field).
std::uint64_t ProcessRssBytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  REQUIRE(f != nullptr);
  unsigned long long size = 0, resident = 0;
  const int n = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  REQUIRE(n == 2);
  return resident * PageBytes();
}

TEST_CASE("capacity is min(count, budget / aligned slot)") {
  SUBCASE("count limits") {
    Arena a = MakeArena({.memory_thr_keyframes = 10, .budget_bytes = 1 << 20, .slot_bytes = 1000});
    CHECK(a.capacity() == 10);
    CHECK(a.slot_bytes() == 1024);  // 1000 rounded up to 64
  }
  SUBCASE("bytes limit") {
    Arena a = MakeArena({.memory_thr_keyframes = 1000, .budget_bytes = 10 * 1024, .slot_bytes = 1000});
    CHECK(a.capacity() == 10);  // 10240 / 1024
  }
  SUBCASE("count only") {
    Arena a = MakeArena({.memory_thr_keyframes = 7, .budget_bytes = 0, .slot_bytes = 64});
    CHECK(a.capacity() == 7);
  }
  SUBCASE("bytes only") {
    Arena a = MakeArena({.memory_thr_keyframes = 0, .budget_bytes = 64 * 5 + 63, .slot_bytes = 64});
    CHECK(a.capacity() == 5);
  }
  auto plan = PlanArena({.memory_thr_keyframes = 3, .budget_bytes = 0, .slot_bytes = 65});
  REQUIRE(std::holds_alternative<ArenaPlan>(plan));
  CHECK(std::get<ArenaPlan>(plan).slot_bytes == 128);
  CHECK(std::get<ArenaPlan>(plan).bytes == 384);
}

TEST_CASE("refuses when full and never grows") {
  Arena a = MakeArena({.memory_thr_keyframes = 3, .budget_bytes = 0, .slot_bytes = 256});
  std::vector<SlotIndex> got;
  for (int i = 0; i < 3; ++i) {
    auto s = a.TryAcquire();
    REQUIRE(s.has_value());
    got.push_back(*s);
  }
  CHECK(a.available() == 0);
  CHECK_FALSE(a.TryAcquire().has_value());
  CHECK_FALSE(a.TryAcquire().has_value());
  CHECK(a.stats().refused == 2);
  CHECK(a.capacity() == 3);
  CHECK(a.in_use() == 3);
}

TEST_CASE("withheld slots cannot be acquired, and resident + withheld never exceeds capacity") {
  Arena a = MakeArena({.memory_thr_keyframes = 5, .budget_bytes = 0, .slot_bytes = 64});
  const auto bounded = [&a] {
    const ArenaStats st = a.stats();
    return st.in_use + st.withheld <= st.capacity && st.available + st.in_use + st.withheld == st.capacity;
  };
  auto s0 = a.TryAcquire();
  auto s1 = a.TryAcquire();
  REQUIRE((s0 && s1));
  CHECK(a.Withhold(2) == 2);  // of the 3 free slots
  CHECK(a.withheld() == 2);
  CHECK(a.available() == 1);
  CHECK(bounded());
  auto s2 = a.TryAcquire();  // the one not withheld
  REQUIRE(s2.has_value());
  CHECK_FALSE(a.TryAcquire().has_value());  // the withheld two stay out of reach
  CHECK(a.stats().refused == 1);
  CHECK(a.in_use() == 3);
  CHECK(bounded());

  // More than is free is clamped: the count is set, never above the free slots.
  CHECK(a.Withhold(100) == 2);
  CHECK(bounded());
  // A slot released meanwhile is not withheld: it can be acquired again.
  a.Release(*s0);
  CHECK(a.available() == 1);
  auto again = a.TryAcquire();
  REQUIRE(again.has_value());
  CHECK_FALSE(a.TryAcquire().has_value());
  CHECK(bounded());

  // Withholding every free slot, then giving them back: loads resume, up to capacity only.
  a.Release(*s1);
  CHECK(a.Withhold(a.capacity()) == 3);
  CHECK(a.available() == 0);
  CHECK_FALSE(a.TryAcquire().has_value());
  CHECK(bounded());
  CHECK(a.Withhold(0) == 0);
  CHECK(a.available() == 3);
  std::uint32_t got = 0;
  while (a.TryAcquire()) ++got;
  CHECK(got == 3);
  CHECK(a.in_use() == a.capacity());
  CHECK(bounded());
  // Withholding touches no slot: nothing was acquired for it (the high-water is real use).
  CHECK(a.stats().high_water == a.capacity());
}

TEST_CASE("slots are disjoint, aligned and exactly slot_bytes") {
  Arena a = MakeArena({.memory_thr_keyframes = 50, .budget_bytes = 0, .slot_bytes = 100});
  std::vector<std::span<std::byte>> spans;
  while (auto s = a.TryAcquire()) spans.push_back(a.Slot(*s));
  REQUIRE(spans.size() == 50);
  std::sort(spans.begin(), spans.end(),
            [](auto x, auto y) { return x.data() < y.data(); });
  for (std::size_t i = 0; i < spans.size(); ++i) {
    CHECK(spans[i].size() == a.slot_bytes());
    CHECK(reinterpret_cast<std::uintptr_t>(spans[i].data()) % Arena::kSlotAlignment == 0);
    if (i > 0) CHECK(spans[i - 1].data() + spans[i - 1].size() <= spans[i].data());
  }
  // Writing a whole slot leaves its neighbours untouched.
  std::fill(spans[10].begin(), spans[10].end(), std::byte{0x42});
  CHECK(spans[9].back() != std::byte{0x42});
  CHECK(spans[11].front() != std::byte{0x42});
}

TEST_CASE("release makes a slot reusable, high-water remembers the peak") {
  Arena a = MakeArena({.memory_thr_keyframes = 4, .budget_bytes = 0, .slot_bytes = 64});
  auto s0 = a.TryAcquire();
  auto s1 = a.TryAcquire();
  auto s2 = a.TryAcquire();
  REQUIRE((s0 && s1 && s2));
  CHECK(a.stats().high_water == 3);
  a.Release(*s1);
  CHECK(a.in_use() == 2);
  CHECK_FALSE(a.InUse(*s1));
  auto again = a.TryAcquire();
  REQUIRE(again.has_value());
  CHECK(*again == *s1);  // LIFO reuse keeps recently used memory hot
  CHECK(a.stats().high_water == 3);
  a.Release(*s0);
  a.Release(*s2);
  a.Release(*again);
  CHECK(a.in_use() == 0);
  CHECK(a.stats().high_water == 3);
  a.ResetCounters();
  CHECK(a.stats().high_water == 0);
  std::set<std::uint32_t> seen;
  while (auto s = a.TryAcquire()) seen.insert(s->value);
  CHECK(seen.size() == 4);
}

TEST_CASE("acquire and release allocate nothing") {
  Arena a = MakeArena({.memory_thr_keyframes = 64, .budget_bytes = 0, .slot_bytes = 4096});
  std::array<SlotIndex, 64> held{};
  test::AllocationCounter counter;
  for (int round = 0; round < 100; ++round) {
    std::size_t n = 0;
    while (auto s = a.TryAcquire()) held[n++] = *s;
    CHECK(n == 64);
    CHECK_FALSE(a.TryAcquire().has_value());
    for (std::size_t i = 0; i < n; ++i) a.Release(held[i]);
  }
  CHECK(counter.allocations() == 0);
  CHECK(counter.deallocations() == 0);
}

TEST_CASE("debug builds poison acquired and released slots") {
  Arena a = MakeArena({.memory_thr_keyframes = 2, .budget_bytes = 0, .slot_bytes = 64});
  if (!a.poisoning()) return;  // release builds skip the fill for speed
  auto s = a.TryAcquire();
  REQUIRE(s.has_value());
  auto bytes = a.Slot(*s);
  CHECK(std::all_of(bytes.begin(), bytes.end(),
                    [](std::byte b) { return b == Arena::kAcquiredPattern; }));
  a.Release(*s);
  CHECK(std::all_of(bytes.begin(), bytes.end(),
                    [](std::byte b) { return b == Arena::kReleasedPattern; }));
}

TEST_CASE("bad sizes give one clear error naming the limit") {
  SUBCASE("zero slot bytes") {
    auto e = MakeError({.memory_thr_keyframes = 10, .budget_bytes = 0, .slot_bytes = 0});
    CHECK(e.code == ArenaErrorCode::kZeroSlotBytes);
    CHECK(e.message.find("slot_bytes") != std::string::npos);
  }
  SUBCASE("no budget at all") {
    auto e = MakeError({.memory_thr_keyframes = 0, .budget_bytes = 0, .slot_bytes = 64});
    CHECK(e.code == ArenaErrorCode::kNoBudget);
  }
  SUBCASE("slot larger than the budget") {
    auto e = MakeError({.memory_thr_keyframes = 10, .budget_bytes = 1000, .slot_bytes = 4096});
    CHECK(e.code == ArenaErrorCode::kSlotLargerThanBudget);
    CHECK(e.message.find("4096") != std::string::npos);
    CHECK(e.message.find("1000") != std::string::npos);
  }
  SUBCASE("budget that rounds to zero slots") {
    auto e = MakeError({.memory_thr_keyframes = 0, .budget_bytes = 100, .slot_bytes = 100});
    CHECK(e.code == ArenaErrorCode::kSlotLargerThanBudget);  // 100 aligns to 128 > 100
  }
  SUBCASE("more than the machine has") {
    auto e = MakeError({.memory_thr_keyframes = 0, .budget_bytes = 1ULL << 50, .slot_bytes = 1 << 20});
    CHECK(e.code == ArenaErrorCode::kExceedsMachine);
    CHECK(e.message.find("exceeds") != std::string::npos);
  }
  SUBCASE("more slots than a SlotIndex can name") {
    auto e = MakeError({.memory_thr_keyframes = 1ULL << 40, .budget_bytes = 0, .slot_bytes = 64});
    CHECK(e.code == ArenaErrorCode::kTooManySlots);
  }
}

TEST_CASE("a pre-faulted arena is resident from Create(), every page") {
  // MAP_POPULATE is silent when it cannot populate (and qemu-user ignores it): Create() checks.
  Arena a = MakeArena({.memory_thr_keyframes = 8, .budget_bytes = 0, .slot_bytes = 1 << 20,
                       .lock = false, .prefault = true});
  for (std::uint32_t i = 0; i < a.capacity(); ++i) {
    CHECK(ResidentBytes(a.Slot(SlotIndex{i})) == a.slot_bytes());
  }
}

TEST_CASE("release_to_os: a slot's pages are taken on use and given back on release") {
  constexpr std::uint32_t kSlots = 16;
  Arena a = MakeArena({.memory_thr_keyframes = kSlots, .budget_bytes = 0,
                       .slot_bytes = (1 << 20) + 100, .lock = false, .prefault = false,
                       .release_to_os = true});
  CHECK(a.releases_to_os());
  CHECK(a.slot_bytes() % PageBytes() == 0);  // whole pages, so a release cannot hit a neighbour
  CHECK(a.slot_bytes() >= (1 << 20) + 100);
  const std::uint64_t total = std::uint64_t{kSlots} * a.slot_bytes();

  std::array<SlotIndex, kSlots> held{};
  const std::uint64_t rss_empty = ProcessRssBytes();
  for (auto& h : held) {
    auto s = a.TryAcquire();
    REQUIRE(s.has_value());
    h = *s;
  }
  for (SlotIndex h : held) std::memset(a.Slot(h).data(), 0x5A, a.Slot(h).size());  // a load
  std::uint64_t resident = 0;
  for (SlotIndex h : held) resident += ResidentBytes(a.Slot(h));
  CHECK(resident == total);
  const std::uint64_t rss_full = ProcessRssBytes();
  MESSAGE("RSS " << rss_empty / 1024 << " KiB -> " << rss_full / 1024 << " KiB after touching "
                 << total / 1024 << " KiB of slots");
  // mincore above is exact; the process's RSS also moves with whatever else it does (under
  // qemu-user, the emulator's own translation buffers), so a quarter of slack.
  CHECK(rss_full >= rss_empty + total * 3 / 4);

  for (SlotIndex h : held) a.Release(h);
  resident = 0;
  for (std::uint32_t i = 0; i < kSlots; ++i) resident += ResidentBytes(a.Slot(SlotIndex{i}));
  CHECK(resident == 0);
  const std::uint64_t rss_released = ProcessRssBytes();
  MESSAGE("RSS after release " << rss_released / 1024 << " KiB");
  CHECK(rss_released + total * 3 / 4 <= rss_full);
  CHECK(a.stats().released_to_os == kSlots);
  CHECK(a.stats().release_failures == 0);
  // A released slot reads as the kernel's zeroed pages, never as the keyframe it held.
  const auto bytes = a.Slot(held[0]);
  CHECK(std::all_of(bytes.begin(), bytes.end(), [](std::byte b) { return b == std::byte{0}; }));
}

TEST_CASE("release_to_os with prefault: an acquired slot is resident before it is written") {
  Arena a = MakeArena({.memory_thr_keyframes = 4, .budget_bytes = 0, .slot_bytes = 1 << 20,
                       .lock = false, .prefault = true, .release_to_os = true});
  // Nothing is resident at start-up: the whole map's arena is a reservation, not a budget.
  for (std::uint32_t i = 0; i < a.capacity(); ++i) CHECK(ResidentBytes(a.Slot(SlotIndex{i})) == 0);
  auto s = a.TryAcquire();
  REQUIRE(s.has_value());
  CHECK(ResidentBytes(a.Slot(*s)) == a.slot_bytes());
  a.Release(*s);
  CHECK(ResidentBytes(a.Slot(*s)) == 0);
}

TEST_CASE("release_to_os keeps the acquire poison and allocates nothing") {
  Arena a = MakeArena({.memory_thr_keyframes = 8, .budget_bytes = 0, .slot_bytes = 8192,
                       .lock = false, .prefault = true, .release_to_os = true});
  if (a.poisoning()) {
    auto s = a.TryAcquire();
    REQUIRE(s.has_value());
    auto bytes = a.Slot(*s);
    CHECK(std::all_of(bytes.begin(), bytes.end(),
                      [](std::byte b) { return b == Arena::kAcquiredPattern; }));
    a.Release(*s);
    auto again = a.TryAcquire();
    REQUIRE(again.has_value());
    CHECK(*again == *s);
    CHECK(std::all_of(bytes.begin(), bytes.end(),
                      [](std::byte b) { return b == Arena::kAcquiredPattern; }));
    a.Release(*again);
  } else {
    MESSAGE("this build does not poison slots (release build): only allocation is checked");
  }
  std::array<SlotIndex, 8> held{};
  test::AllocationCounter counter;
  for (int round = 0; round < 20; ++round) {
    std::size_t n = 0;
    while (auto s = a.TryAcquire()) held[n++] = *s;
    CHECK(n == 8);
    for (std::size_t i = 0; i < n; ++i) a.Release(held[i]);
  }
  CHECK(counter.allocations() == 0);
  CHECK(counter.deallocations() == 0);
}

TEST_CASE("lock with release_to_os is refused, naming both") {
  auto e = MakeError({.memory_thr_keyframes = 4, .budget_bytes = 0, .slot_bytes = 4096,
                      .lock = true, .prefault = false, .release_to_os = true});
  CHECK(e.code == ArenaErrorCode::kConflictingOptions);
  CHECK(e.message.find("lock") != std::string::npos);
  CHECK(e.message.find("release_to_os") != std::string::npos);
}

TEST_CASE("a moved-from arena owns nothing") {
  Arena a = MakeArena({.memory_thr_keyframes = 2, .budget_bytes = 0, .slot_bytes = 64});
  auto s = a.TryAcquire();
  Arena b = std::move(a);
  CHECK(b.in_use() == 1);
  CHECK(b.InUse(*s));
  CHECK(a.capacity() == 0);  // NOLINT(bugprone-use-after-move): checking the moved-from state
  CHECK_FALSE(a.TryAcquire().has_value());
}

}  // namespace
}  // namespace zm
