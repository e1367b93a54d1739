// Per-process memory telemetry for the experiment: resident memory (anonymous and file-backed
// apart: the co-tenant's weights are a file mapping the kernel may evict), minor and major page
// faults, read from /proc/<pid>/stat and /proc/<pid>/statm; and getrusage() for this process and
// its reaped children.
//
// Under qemu-user, /proc/<own pid>/stat is the emulator's fabrication (faults read 0): sample
// children, and this process with SampleRusage().
//
// Invariants: ProcessSampler::Sample() and SampleRusage() never allocate (files opened once,
// read with pread into a stack buffer), so they can run every tick. A sampler of a process that
// has exited reports alive = false and zeros, never stale numbers.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string_view>

#include "common/status.h"

namespace zm {

// The fields of /proc/<pid>/stat the harness uses.
struct ProcStat {
  char state = '?';                // R, S, D, Z, ...
  std::uint64_t minor_faults = 0;  // field 10
  std::uint64_t major_faults = 0;  // field 12
  std::uint64_t start_ticks = 0;   // field 22, clock ticks after boot
  std::uint64_t rss_pages = 0;     // field 24
};
// Parses the text of /proc/<pid>/stat (the command name may hold spaces and parentheses: fields
// are counted from the last ')'). False when the text is not a stat line.
[[nodiscard]] bool ParseProcStat(std::string_view text, ProcStat* out) noexcept;

// A process's start time in clock ticks since boot; 0 when it does not exist. Read through
// /proc/<pid>/task/<pid>/stat, which qemu-user does not rewrite (it fakes /proc/self/stat).
[[nodiscard]] std::uint64_t ProcessStartTicks(pid_t pid);

struct ProcessSample {
  bool alive = false;                // the process exists (a zombie counts as gone)
  std::uint64_t rss_bytes = 0;       // resident set (statm resident)
  std::uint64_t rss_anon_bytes = 0;  // resident - shared: heap, arena, KV cache
  std::uint64_t rss_file_bytes = 0;  // statm shared: file-backed and shmem pages (mmap'ed weights)
  std::uint64_t minor_faults = 0;    // since the process started
  std::uint64_t major_faults = 0;    // faults that read from disk or swap (e.g. evicted weights)
  std::uint64_t swap_bytes = 0;      // swapped out (/proc/<pid>/status VmSwap)
};

class ProcessSampler {
 public:
  // Opens /proc/<pid>/stat, statm and status. NotFound when the process does not exist.
  [[nodiscard]] static Result<ProcessSampler> Open(pid_t pid);

  ProcessSampler() = default;
  ProcessSampler(ProcessSampler&& other) noexcept;
  ProcessSampler& operator=(ProcessSampler&& other) noexcept;
  ProcessSampler(const ProcessSampler&) = delete;
  ProcessSampler& operator=(const ProcessSampler&) = delete;
  ~ProcessSampler();

  // Allocation-free. alive = false (and zeros) once the process has exited.
  [[nodiscard]] ProcessSample Sample() const noexcept;
  [[nodiscard]] pid_t pid() const noexcept { return pid_; }

 private:
  pid_t pid_ = -1;
  int stat_fd_ = -1;
  int statm_fd_ = -1;
  int status_fd_ = -1;  // /proc/<pid>/status, for VmSwap
  std::uint64_t page_bytes_ = 4096;
};

// getrusage(2) for this process and for its children that have been waited for.
struct RusageSample {
  std::uint64_t self_minor_faults = 0;
  std::uint64_t self_major_faults = 0;
  std::uint64_t self_max_rss_bytes = 0;
  std::uint64_t children_minor_faults = 0;
  std::uint64_t children_major_faults = 0;
  std::uint64_t children_max_rss_bytes = 0;  // the largest of the reaped children
};
[[nodiscard]] RusageSample SampleRusage() noexcept;

}  // namespace zm
