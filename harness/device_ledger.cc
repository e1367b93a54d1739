// Device ledger implementation: one fixed-size header of lock-free atomics in a MAP_SHARED file.
// The file is initialised under an exclusive flock so that two processes opening it at once
// agree on one header; after that nothing takes a lock: slots are claimed by compare-and-swap
// on their state, and grants by compare-and-swap on the device-wide sum.
#include "harness/device_ledger.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <new>

namespace zm {
namespace ledger_internal {

static_assert(std::atomic<std::uint64_t>::is_always_lock_free,
              "the ledger shares atomics between processes: they must be lock-free");
static_assert(std::atomic<std::uint32_t>::is_always_lock_free);

constexpr std::uint64_t kMagic = 0x52474445444c4d5aULL;  // "ZMLDEDGR"
constexpr std::uint32_t kVersion = 1;

enum : std::uint32_t { kFree = 0, kClaimed = 1, kActive = 2 };

struct TenantRecord {
  std::atomic<std::uint32_t> state{kFree};
  std::atomic<std::int32_t> pid{0};
  std::atomic<std::uint64_t> bytes{0};
  std::atomic<std::uint64_t> demand{0};
  std::atomic<std::uint64_t> peak{0};
  std::atomic<std::uint64_t> oom_events{0};
  char name[kLedgerNameBytes] = {};
};

struct Header {
  std::uint64_t magic = 0;
  std::uint32_t version = 0;
  std::uint32_t max_tenants = 0;
  std::atomic<std::uint64_t> device_bytes{0};
  std::atomic<std::uint64_t> sum{0};
  std::atomic<std::uint64_t> peak{0};
  std::atomic<std::uint64_t> oom_events{0};
  TenantRecord tenants[kLedgerMaxTenants];
};

struct Mapping {
  Header* header = nullptr;
  ~Mapping() {
    if (header != nullptr) munmap(header, sizeof(Header));
  }
};

namespace {

void AtomicMax(std::atomic<std::uint64_t>& a, std::uint64_t v) noexcept {
  std::uint64_t cur = a.load(std::memory_order_relaxed);
  while (cur < v && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

// Sets r's grant to `bytes` if the device has room. Only r's owner calls this for r.
bool Grant(Header& h, TenantRecord& r, std::uint64_t bytes) noexcept {
  const std::uint64_t old = r.bytes.load(std::memory_order_relaxed);
  if (bytes <= old) {
    h.sum.fetch_sub(old - bytes, std::memory_order_acq_rel);
    r.bytes.store(bytes, std::memory_order_relaxed);
    r.demand.store(bytes, std::memory_order_release);
    return true;
  }
  const std::uint64_t delta = bytes - old;
  const std::uint64_t total = h.device_bytes.load(std::memory_order_relaxed);
  std::uint64_t sum = h.sum.load(std::memory_order_relaxed);
  for (;;) {
    if (sum > total || delta > total - sum) {
      r.demand.store(bytes, std::memory_order_release);
      r.oom_events.fetch_add(1, std::memory_order_relaxed);
      h.oom_events.fetch_add(1, std::memory_order_acq_rel);
      return false;
    }
    if (h.sum.compare_exchange_weak(sum, sum + delta, std::memory_order_acq_rel)) break;
  }
  r.bytes.store(bytes, std::memory_order_relaxed);
  r.demand.store(bytes, std::memory_order_release);
  AtomicMax(r.peak, bytes);
  AtomicMax(h.peak, sum + delta);
  return true;
}

void FreeRecord(Header& h, TenantRecord& r) noexcept {
  h.sum.fetch_sub(r.bytes.exchange(0, std::memory_order_acq_rel), std::memory_order_acq_rel);
  r.demand.store(0, std::memory_order_relaxed);
  r.pid.store(0, std::memory_order_relaxed);
  r.state.store(kFree, std::memory_order_release);
}

}  // namespace
}  // namespace ledger_internal

using ledger_internal::Header;
using ledger_internal::Mapping;
using ledger_internal::TenantRecord;

// ---- LedgerTenant ----

LedgerTenant::LedgerTenant(LedgerTenant&& other) noexcept
    : mapping_(std::move(other.mapping_)), record_(other.record_) {
  other.record_ = nullptr;
}

LedgerTenant& LedgerTenant::operator=(LedgerTenant&& other) noexcept {
  if (this != &other) {
    Release();
    mapping_ = std::move(other.mapping_);
    record_ = other.record_;
    other.record_ = nullptr;
  }
  return *this;
}

LedgerTenant::~LedgerTenant() { Release(); }

bool LedgerTenant::TryUpdate(std::uint64_t bytes) noexcept {
  if (record_ == nullptr) return false;
  return ledger_internal::Grant(*mapping_->header, *record_, bytes);
}

Status LedgerTenant::Update(std::uint64_t bytes) noexcept {
  if (record_ == nullptr) return FailedPrecondition("ledger tenant is not registered");
  if (TryUpdate(bytes)) return Status::Ok();
  // Building the message allocates; this is the failure path only.
  return ResourceExhausted(std::string("device ledger: tenant '") + record_->name + "' asked for " +
                           std::to_string(bytes) + " bytes, the device total " +
                           std::to_string(mapping_->header->device_bytes.load()) +
                           " would be exceeded (" + std::to_string(mapping_->header->sum.load()) +
                           " granted)");
}

void LedgerTenant::Release() noexcept {
  if (record_ == nullptr) return;
  ledger_internal::FreeRecord(*mapping_->header, *record_);
  record_ = nullptr;
  mapping_.reset();
}

std::uint64_t LedgerTenant::bytes() const noexcept {
  return record_ == nullptr ? 0 : record_->bytes.load(std::memory_order_relaxed);
}

std::uint64_t LedgerTenant::oom_events() const noexcept {
  return record_ == nullptr ? 0 : record_->oom_events.load(std::memory_order_relaxed);
}

// ---- DeviceLedger ----

std::string DeviceLedger::DefaultLedgerPath() {
  std::string dir = "/dev/shm";
  struct stat st {};
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    const char* tmp = std::getenv("TMPDIR");
    dir = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  }
  return dir + "/zonemap-ledger-" + std::to_string(getuid());
}

Result<DeviceLedger> DeviceLedger::Open(const std::string& path, std::uint64_t device_bytes) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return IoError("device ledger '" + path + "': open: " + std::strerror(errno));
  struct FdCloser {
    int fd;
    ~FdCloser() { ::close(fd); }
  } closer{fd};
  if (flock(fd, LOCK_EX) != 0) {
    return IoError("device ledger '" + path + "': flock: " + std::strerror(errno));
  }
  struct stat st {};
  if (fstat(fd, &st) != 0) return IoError("device ledger '" + path + "': fstat failed");
  const bool fresh = st.st_size == 0;
  if (fresh) {
    if (device_bytes == 0) {
      return InvalidArgument("device ledger '" + path +
                             "' does not exist yet: its device total must be given");
    }
    if (ftruncate(fd, static_cast<off_t>(sizeof(Header))) != 0) {
      return IoError("device ledger '" + path + "': ftruncate: " + std::strerror(errno));
    }
  } else if (static_cast<std::uint64_t>(st.st_size) != sizeof(Header)) {
    return Corrupt("device ledger '" + path + "' has " + std::to_string(st.st_size) +
                   " bytes, expected " + std::to_string(sizeof(Header)) +
                   " (not a ledger, or another version: remove it)");
  }
  void* addr = mmap(nullptr, sizeof(Header), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (addr == MAP_FAILED) return IoError("device ledger '" + path + "': mmap: " + std::strerror(errno));
  auto mapping = std::make_shared<Mapping>();
  if (fresh) {
    Header* h = new (addr) Header();
    h->device_bytes.store(device_bytes);
    h->version = ledger_internal::kVersion;
    h->max_tenants = kLedgerMaxTenants;
    std::atomic_thread_fence(std::memory_order_release);
    h->magic = ledger_internal::kMagic;
    mapping->header = h;
  } else {
    // The file was initialised by a process holding the same flock: its header is complete.
    mapping->header = static_cast<Header*>(addr);
    const Header& h = *mapping->header;
    if (h.magic != ledger_internal::kMagic || h.version != ledger_internal::kVersion ||
        h.max_tenants != kLedgerMaxTenants) {
      return Corrupt("device ledger '" + path + "' has a bad header (remove it)");
    }
    if (device_bytes != 0 && h.device_bytes.load() != device_bytes) {
      return InvalidArgument("device ledger '" + path + "' holds a device of " +
                             std::to_string(h.device_bytes.load()) + " bytes, not " +
                             std::to_string(device_bytes) + " (remove it or attach with 0)");
    }
  }
  flock(fd, LOCK_UN);
  DeviceLedger ledger;
  ledger.mapping_ = std::move(mapping);
  ledger.path_ = path;
  return ledger;
}

Status DeviceLedger::Remove(const std::string& path) {
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) {
    return IoError("device ledger '" + path + "': unlink: " + std::strerror(errno));
  }
  return Status::Ok();
}

Result<LedgerTenant> DeviceLedger::Register(std::string_view name, std::uint64_t bytes) {
  if (name.empty() || name.size() >= kLedgerNameBytes) {
    return InvalidArgument("device ledger: tenant name '" + std::string(name) + "' must have 1 to " +
                           std::to_string(kLedgerNameBytes - 1) + " bytes");
  }
  Header& h = *mapping_->header;
  for (TenantRecord& r : h.tenants) {
    std::uint32_t expected = ledger_internal::kFree;
    if (!r.state.compare_exchange_strong(expected, ledger_internal::kClaimed)) continue;
    std::memset(r.name, 0, sizeof r.name);
    std::memcpy(r.name, name.data(), name.size());
    r.pid.store(static_cast<std::int32_t>(getpid()));
    r.bytes.store(0);
    r.demand.store(0);
    r.peak.store(0);
    r.oom_events.store(0);
    r.state.store(ledger_internal::kActive, std::memory_order_release);
    if (!ledger_internal::Grant(h, r, bytes)) {
      ledger_internal::FreeRecord(h, r);
      return ResourceExhausted("device ledger: '" + std::string(name) + "' needs " +
                               std::to_string(bytes) + " bytes but only " +
                               std::to_string(free_bytes()) + " of " +
                               std::to_string(device_bytes()) + " are free");
    }
    LedgerTenant t;
    t.mapping_ = mapping_;
    t.record_ = &r;
    return t;
  }
  return OutOfRange("device ledger '" + path_ + "': all " + std::to_string(kLedgerMaxTenants) +
                    " tenant slots are taken (ReapDeadTenants() frees those of dead processes)");
}

std::uint32_t DeviceLedger::ReapDeadTenants() {
  std::uint32_t reaped = 0;
  Header& h = *mapping_->header;
  for (TenantRecord& r : h.tenants) {
    if (r.state.load() != ledger_internal::kActive) continue;
    const pid_t pid = r.pid.load();
    if (pid <= 0 || pid == getpid()) continue;
    if (kill(pid, 0) == 0 || errno != ESRCH) continue;
    std::uint32_t expected = ledger_internal::kActive;
    if (r.state.compare_exchange_strong(expected, ledger_internal::kClaimed)) {
      ledger_internal::FreeRecord(h, r);
      ++reaped;
    }
  }
  return reaped;
}

std::uint64_t DeviceLedger::device_bytes() const noexcept {
  return mapping_->header->device_bytes.load(std::memory_order_relaxed);
}
std::uint64_t DeviceLedger::sum_bytes() const noexcept {
  return mapping_->header->sum.load(std::memory_order_acquire);
}
std::uint64_t DeviceLedger::peak_sum_bytes() const noexcept {
  return mapping_->header->peak.load(std::memory_order_acquire);
}
std::uint64_t DeviceLedger::oom_events() const noexcept {
  return mapping_->header->oom_events.load(std::memory_order_acquire);
}
std::uint64_t DeviceLedger::free_bytes() const noexcept {
  const std::uint64_t total = device_bytes();
  const std::uint64_t sum = sum_bytes();
  return sum >= total ? 0 : total - sum;
}

bool DeviceLedger::OverCommitted() const noexcept {
  const Header& h = *mapping_->header;
  std::uint64_t demand = 0;
  for (const TenantRecord& r : h.tenants) {
    if (r.state.load(std::memory_order_acquire) != ledger_internal::kActive) continue;
    const std::uint64_t b = r.bytes.load(std::memory_order_relaxed);
    const std::uint64_t d = r.demand.load(std::memory_order_relaxed);
    demand += d > b ? d : b;
  }
  return demand > h.device_bytes.load(std::memory_order_relaxed);
}

void DeviceLedger::ResetPeak() noexcept {
  Header& h = *mapping_->header;
  h.peak.store(h.sum.load());
}

LedgerSnapshot DeviceLedger::Snapshot() const {
  const Header& h = *mapping_->header;
  LedgerSnapshot s;
  s.device_bytes = h.device_bytes.load();
  s.sum_bytes = h.sum.load();
  s.peak_sum_bytes = h.peak.load();
  s.oom_events = h.oom_events.load();
  for (const TenantRecord& r : h.tenants) {
    if (r.state.load() != ledger_internal::kActive) continue;
    LedgerTenantInfo t;
    t.name.assign(r.name, strnlen(r.name, sizeof r.name));
    t.pid = r.pid.load();
    t.bytes = r.bytes.load();
    t.demand_bytes = r.demand.load();
    t.peak_bytes = r.peak.load();
    t.oom_events = r.oom_events.load();
    s.demand_bytes += t.demand_bytes > t.bytes ? t.demand_bytes : t.bytes;
    s.tenants.push_back(std::move(t));
  }
  return s;
}

}  // namespace zm
