// setrlimit caps with an enforcement probe, and the counted allocation-failure boundary.
#include "runtime/memory_cap.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include "arena/sanitizers.h"

namespace zm {
namespace {

std::atomic<std::uint64_t> g_alloc_failures{0};

std::uint64_t StatusField(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t n = std::strlen(field);
  while (std::getline(in, line)) {
    if (line.compare(0, n, field) == 0 && line.size() > n && line[n] == ':') {
      return std::strtoull(line.c_str() + n + 1, nullptr, 10) * 1024;  // "kB"
    }
  }
  return 0;
}

std::size_t PageBytes() {
  const long p = sysconf(_SC_PAGESIZE);
  return p > 0 ? static_cast<std::size_t>(p) : 4096;
}

std::size_t RoundUpToPages(std::size_t bytes) {
  const std::size_t page = PageBytes();
  return (bytes + page - 1) / page * page;
}

// True if the kernel refuses a private writable mapping of `bytes` now.
bool ProbeRefused(std::uint64_t bytes) {
  void* p = mmap(nullptr, static_cast<std::size_t>(bytes), PROT_READ | PROT_WRITE,
                 MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) return true;
  munmap(p, static_cast<std::size_t>(bytes));
  return false;
}

}  // namespace

const char* CapResourceName(CapResource r) {
  switch (r) {
    case CapResource::kAddressSpace: return "RLIMIT_AS";
    case CapResource::kData: return "RLIMIT_DATA";
    case CapResource::kNone: break;
  }
  return "none";
}

bool BuiltWithAddressSanitizer() noexcept {
#if ZM_ASAN
  return true;
#else
  return false;
#endif
}

std::uint64_t ProcessAddressSpaceBytes() { return StatusField("VmSize"); }
std::uint64_t ProcessDataBytes() { return StatusField("VmData"); }

Result<CapReport> ApplyProcessCap(std::uint64_t cap_bytes, CapMode mode) {
  CapReport report;
  report.cap_bytes = cap_bytes;
  report.sanitizer = BuiltWithAddressSanitizer();
  if (cap_bytes == 0) {
    report.note = "no process cap (map.process_cap_bytes = 0)";
    return report;
  }
  if (mode == CapMode::kAddressSpace && report.sanitizer) {
    return FailedPrecondition(
        "RLIMIT_AS cannot cap an AddressSanitizer build: its shadow memory already reserves "
        "terabytes of address space (use RLIMIT_DATA or the automatic choice)");
  }
  const bool use_data = mode == CapMode::kData || (mode == CapMode::kAuto && report.sanitizer);
  int resource = RLIMIT_AS;
  if (use_data) {
    resource = RLIMIT_DATA;
    report.resource = CapResource::kData;
    if (report.sanitizer) {
      report.baseline_bytes = ProcessDataBytes();
      report.limit_bytes = report.baseline_bytes + cap_bytes;
      report.note =
          "RLIMIT_DATA = data already mapped + cap: AddressSanitizer reserves terabytes of "
          "virtual memory, so RLIMIT_AS cannot be used and only growth is capped";
    } else {
      report.limit_bytes = cap_bytes;
      const std::uint64_t used = ProcessDataBytes();
      if (used > cap_bytes) {
        return FailedPrecondition("process cap " + std::to_string(cap_bytes) +
                                  " bytes is below the data this process already maps (" +
                                  std::to_string(used) + " bytes)");
      }
      report.note = "RLIMIT_DATA caps private writable memory (heap and anonymous mappings)";
    }
  } else {
    report.resource = CapResource::kAddressSpace;
    report.limit_bytes = cap_bytes;
    const std::uint64_t used = ProcessAddressSpaceBytes();
    if (used > cap_bytes) {
      return FailedPrecondition("process cap " + std::to_string(cap_bytes) +
                                " bytes is below the address space this process already maps (" +
                                std::to_string(used) + " bytes)");
    }
    report.note = "RLIMIT_AS caps the whole address space (every mapping counts)";
  }
  struct rlimit lim {};
  if (getrlimit(resource, &lim) != 0) {
    return IoError(std::string("getrlimit(") + CapResourceName(report.resource) +
                   "): " + std::strerror(errno));
  }
  if (lim.rlim_max != RLIM_INFINITY && report.limit_bytes > lim.rlim_max) {
    return FailedPrecondition(std::string(CapResourceName(report.resource)) + " cap " +
                              std::to_string(report.limit_bytes) + " exceeds the hard limit " +
                              std::to_string(lim.rlim_max));
  }
  lim.rlim_cur = static_cast<rlim_t>(report.limit_bytes);
  if (setrlimit(resource, &lim) != 0) {
    return IoError(std::string("setrlimit(") + CapResourceName(report.resource) +
                   "): " + std::strerror(errno));
  }
  // One mapping larger than the whole cap must be refused if the cap is real.
  report.enforced = ProbeRefused(cap_bytes + PageBytes());
  if (!report.enforced) {
    report.note += "; NOT enforced: a mapping beyond the cap was granted (qemu-user ignores "
                   "RLIMIT_AS/RLIMIT_DATA; so do some containers)";
  }
  return report;
}

void CountAllocFailure() noexcept { g_alloc_failures.fetch_add(1, std::memory_order_relaxed); }

std::uint64_t AllocFailureCount() noexcept {
  return g_alloc_failures.load(std::memory_order_relaxed);
}

void* TryMalloc(std::size_t bytes) noexcept {
  if (bytes == 0) return nullptr;
  void* p = std::malloc(bytes);
  if (p == nullptr) CountAllocFailure();
  return p;
}

void* TryMapBytes(std::size_t bytes) noexcept {
  if (bytes == 0) return nullptr;
  void* p = mmap(nullptr, RoundUpToPages(bytes), PROT_READ | PROT_WRITE,
                 MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) {
    CountAllocFailure();
    return nullptr;
  }
  return p;
}

void UnmapBytes(void* p, std::size_t bytes) noexcept {
  if (p != nullptr) munmap(p, RoundUpToPages(bytes));
}

}  // namespace zm
