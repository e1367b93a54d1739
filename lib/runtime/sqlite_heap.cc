// SQLite's allocator over one reservation (see sqlite_heap.h).
#include "runtime/sqlite_heap.h"

#include <sqlite3.h>
#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>

#include "arena/sanitizers.h"

#if ZM_ASAN
#include <sanitizer/asan_interface.h>
#define ZM_HEAP_POISON(p, n) ASAN_POISON_MEMORY_REGION((p), (n))
#define ZM_HEAP_UNPOISON(p, n) ASAN_UNPOISON_MEMORY_REGION((p), (n))
#else
#define ZM_HEAP_POISON(p, n) ((void)(p), (void)(n))
#define ZM_HEAP_UNPOISON(p, n) ((void)(p), (void)(n))
#endif

namespace zm {
namespace {

// Every block: a 16-byte header (its class and, while free, the next free block), then the
// payload. 16 keeps SQLite's 8-byte alignment with room to spare.
struct Header {
  std::uint32_t size_class;
  std::uint32_t unused;
  Header* next_free;
};
static_assert(sizeof(Header) == 16);
constexpr std::size_t kHeaderBytes = sizeof(Header);
constexpr int kMinShift = 4;  // class c holds 2^(c+4) bytes; 32 B is the smallest useful block
constexpr int kClasses = 40;

std::size_t ClassBytes(int c) { return std::size_t{1} << (c + kMinShift); }

// The smallest class whose block holds `payload` bytes after the header.
int ClassFor(std::size_t payload) {
  const std::size_t total = payload + kHeaderBytes;
  int c = 0;
  while (c < kClasses && ClassBytes(c) < total) ++c;
  return c;
}

SqliteHeap* g_heap = nullptr;  // SQLite's callbacks carry no context: one heap per process

void* XMalloc(int n) { return g_heap->Allocate(static_cast<std::size_t>(std::max(n, 1))); }
void XFree(void* p) { g_heap->Free(p); }
void* XRealloc(void* p, int n) {
  return g_heap->Reallocate(p, static_cast<std::size_t>(std::max(n, 1)));
}
int XSize(void* p) { return static_cast<int>(g_heap->UsableSize(p)); }
int XRoundup(int n) {
  return static_cast<int>(SqliteHeap::RoundUp(static_cast<std::size_t>(std::max(n, 1))));
}
int XInit(void*) { return SQLITE_OK; }
void XShutdown(void*) {}

}  // namespace

struct SqliteHeap::Impl {
  std::byte* base = nullptr;
  std::size_t capacity = 0;
  std::size_t carved = 0;
  int max_class = 0;  // classes above are refused (blocks larger than a quarter of the heap)
  std::array<Header*, kClasses> free{};
  mutable std::mutex mu;
  SqliteHeapStats stats;
  sqlite3_mem_methods previous{};
};

Result<std::unique_ptr<SqliteHeap>> SqliteHeap::Install(std::uint64_t capacity_bytes) {
  if (capacity_bytes < (std::uint64_t{1} << 20)) {
    return InvalidArgument("the SQLite heap needs at least 1 MiB, not " +
                           std::to_string(capacity_bytes) + " bytes");
  }
  if (g_heap != nullptr) return FailedPrecondition("a SQLite heap is already installed");
  std::unique_ptr<SqliteHeap> heap(new SqliteHeap());
  heap->impl_ = std::make_unique<Impl>();
  Impl& m = *heap->impl_;
  void* p = ::mmap(nullptr, capacity_bytes, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) {
    return ResourceExhausted("reserving " + std::to_string(capacity_bytes) +
                             " bytes for SQLite's heap: " + std::strerror(errno));
  }
  m.base = static_cast<std::byte*>(p);
  m.capacity = capacity_bytes;
  m.stats.capacity_bytes = capacity_bytes;
  while (m.max_class + 1 < kClasses && ClassBytes(m.max_class + 1) <= capacity_bytes / 4) {
    ++m.max_class;
  }
  ZM_HEAP_POISON(m.base, m.capacity);

  // SQLite's configuration may only change while it is shut down (no connection open).
  sqlite3_shutdown();
  if (sqlite3_config(SQLITE_CONFIG_GETMALLOC, &m.previous) != SQLITE_OK) {
    ::munmap(m.base, m.capacity);
    return Internal("SQLite refused SQLITE_CONFIG_GETMALLOC");
  }
  static const sqlite3_mem_methods kMethods = {XMalloc, XFree,   XRealloc, XSize,
                                               XRoundup, XInit, XShutdown, nullptr};
  g_heap = heap.get();
  if (sqlite3_config(SQLITE_CONFIG_MALLOC, &kMethods) != SQLITE_OK ||
      sqlite3_initialize() != SQLITE_OK) {
    g_heap = nullptr;
    sqlite3_config(SQLITE_CONFIG_MALLOC, &m.previous);
    ::munmap(m.base, m.capacity);
    return Internal("SQLite refused its heap (is a database still open?)");
  }
  return heap;
}

SqliteHeap::~SqliteHeap() {
  if (!impl_) return;
  sqlite3_shutdown();
  sqlite3_config(SQLITE_CONFIG_MALLOC, &impl_->previous);
  sqlite3_initialize();
  g_heap = nullptr;
  ZM_HEAP_UNPOISON(impl_->base, impl_->capacity);
  ::munmap(impl_->base, impl_->capacity);
}

SqliteHeapStats SqliteHeap::stats() const {
  const std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->stats;
}

std::size_t SqliteHeap::RoundUp(std::size_t bytes) {
  const int c = ClassFor(bytes);
  return c < kClasses ? ClassBytes(c) - kHeaderBytes : bytes;
}

void* SqliteHeap::Allocate(std::size_t bytes) {
  Impl& m = *impl_;
  const int c = ClassFor(bytes);
  const std::lock_guard<std::mutex> lock(m.mu);
  if (c > m.max_class) {
    ++m.stats.refused;
    return nullptr;
  }
  Header* h = m.free[static_cast<std::size_t>(c)];
  if (h != nullptr) {
    ZM_HEAP_UNPOISON(h, kHeaderBytes);
    m.free[static_cast<std::size_t>(c)] = h->next_free;
  } else {
    const std::size_t size = ClassBytes(c);
    if (size > m.capacity - m.carved) {  // the reservation is used up: refuse, never fall back
      ++m.stats.refused;
      return nullptr;
    }
    h = reinterpret_cast<Header*>(m.base + m.carved);
    m.carved += size;
    m.stats.carved_bytes = m.carved;
    ZM_HEAP_UNPOISON(h, kHeaderBytes);
  }
  h->size_class = static_cast<std::uint32_t>(c);
  h->next_free = nullptr;
  ZM_HEAP_POISON(h, kHeaderBytes);
  m.stats.in_use_bytes += ClassBytes(c);
  ++m.stats.allocations;
  void* payload = reinterpret_cast<std::byte*>(h) + kHeaderBytes;
  ZM_HEAP_UNPOISON(payload, ClassBytes(c) - kHeaderBytes);
  return payload;
}

void SqliteHeap::Free(void* p) {
  if (p == nullptr) return;
  Impl& m = *impl_;
  auto* h = reinterpret_cast<Header*>(static_cast<std::byte*>(p) - kHeaderBytes);
  const std::lock_guard<std::mutex> lock(m.mu);
  ZM_HEAP_UNPOISON(h, kHeaderBytes);
  const std::uint32_t c = h->size_class;
  h->next_free = m.free[c];
  m.free[c] = h;
  ZM_HEAP_POISON(h, ClassBytes(static_cast<int>(c)));  // the payload too: use after free
  m.stats.in_use_bytes -= ClassBytes(static_cast<int>(c));
}

std::size_t SqliteHeap::UsableSize(const void* p) const {
  if (p == nullptr) return 0;
  const auto* h =
      reinterpret_cast<const Header*>(static_cast<const std::byte*>(p) - kHeaderBytes);
  ZM_HEAP_UNPOISON(h, kHeaderBytes);
  const std::uint32_t c = h->size_class;
  ZM_HEAP_POISON(h, kHeaderBytes);
  return ClassBytes(static_cast<int>(c)) - kHeaderBytes;
}

void* SqliteHeap::Reallocate(void* p, std::size_t bytes) {
  if (p == nullptr) return Allocate(bytes);
  const std::size_t have = UsableSize(p);
  if (ClassFor(bytes) == ClassFor(have)) return p;  // same block size: nothing to move
  void* q = Allocate(bytes);
  if (q == nullptr) return nullptr;  // realloc's contract: the old block stays valid
  std::memcpy(q, p, std::min(have, bytes));
  Free(p);
  return q;
}

}  // namespace zm
