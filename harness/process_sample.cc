// /proc and getrusage sampling. See process_sample.h.
#include "harness/process_sample.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <utility>

namespace zm {
namespace {

// Reads a small /proc file from offset 0 into buf (NUL-free view). Empty on error.
std::string_view PreadAll(int fd, char* buf, std::size_t size) noexcept {
  if (fd < 0) return {};
  const ssize_t n = pread(fd, buf, size, 0);
  if (n <= 0) return {};
  return {buf, static_cast<std::size_t>(n)};
}

// Next space-separated unsigned number of `text` from *pos; false when there is none.
bool NextNumber(std::string_view text, std::size_t* pos, std::uint64_t* out) noexcept {
  std::size_t i = *pos;
  while (i < text.size() && text[i] == ' ') ++i;
  // Some fields are signed; a negative value is reported as 0.
  bool negative = false;
  if (i < text.size() && text[i] == '-') {
    negative = true;
    ++i;
  }
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data() + i, text.data() + text.size(), v);
  if (ec != std::errc()) return false;
  *pos = static_cast<std::size_t>(end - text.data());
  *out = negative ? 0 : v;
  return true;
}

}  // namespace

bool ParseProcStat(std::string_view text, ProcStat* out) noexcept {
  const std::size_t paren = text.rfind(')');
  if (paren == std::string_view::npos || paren + 3 >= text.size()) return false;
  // After "pid (comm) ": field 3 is the state character, then numbers from field 4 on.
  out->state = text[paren + 2];
  std::size_t pos = paren + 3;
  std::uint64_t v = 0;
  for (int field = 4; field <= 24; ++field) {
    if (!NextNumber(text, &pos, &v)) return false;
    if (field == 10) out->minor_faults = v;
    if (field == 12) out->major_faults = v;
    if (field == 22) out->start_ticks = v;
    if (field == 24) out->rss_pages = v;
  }
  return true;
}

std::uint64_t ProcessStartTicks(pid_t pid) {
  char path[64];
  std::snprintf(path, sizeof path, "/proc/%d/task/%d/stat", static_cast<int>(pid),
                static_cast<int>(pid));
  const int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char buf[1024];
  const std::string_view text = PreadAll(fd, buf, sizeof buf);
  close(fd);
  ProcStat st;
  if (!ParseProcStat(text, &st) || st.state == 'Z' || st.state == 'X') return 0;
  return st.start_ticks;
}

Result<ProcessSampler> ProcessSampler::Open(pid_t pid) {
  ProcessSampler s;
  s.pid_ = pid;
  const long page = sysconf(_SC_PAGE_SIZE);
  if (page > 0) s.page_bytes_ = static_cast<std::uint64_t>(page);
  char path[64];
  // The whole process's faults (the task/<tid>/stat files count one thread's). qemu-user
  // rewrites this file with zeros for its own process only; the harness samples its children.
  std::snprintf(path, sizeof path, "/proc/%d/stat", static_cast<int>(pid));
  s.stat_fd_ = open(path, O_RDONLY | O_CLOEXEC);
  if (s.stat_fd_ < 0) {
    return NotFound(std::string("process sampler: cannot open ") + path + ": " +
                    std::strerror(errno));
  }
  std::snprintf(path, sizeof path, "/proc/%d/statm", static_cast<int>(pid));
  s.statm_fd_ = open(path, O_RDONLY | O_CLOEXEC);
  if (s.statm_fd_ < 0) {
    return NotFound(std::string("process sampler: cannot open ") + path + ": " +
                    std::strerror(errno));
  }
  std::snprintf(path, sizeof path, "/proc/%d/status", static_cast<int>(pid));
  s.status_fd_ = open(path, O_RDONLY | O_CLOEXEC);  // -1 tolerated: swap then reads 0
  return s;
}

ProcessSampler::ProcessSampler(ProcessSampler&& other) noexcept { *this = std::move(other); }

ProcessSampler& ProcessSampler::operator=(ProcessSampler&& other) noexcept {
  if (this != &other) {
    if (stat_fd_ >= 0) close(stat_fd_);
    if (statm_fd_ >= 0) close(statm_fd_);
    if (status_fd_ >= 0) close(status_fd_);
    pid_ = std::exchange(other.pid_, -1);
    status_fd_ = std::exchange(other.status_fd_, -1);
    stat_fd_ = std::exchange(other.stat_fd_, -1);
    statm_fd_ = std::exchange(other.statm_fd_, -1);
    page_bytes_ = other.page_bytes_;
  }
  return *this;
}

ProcessSampler::~ProcessSampler() {
  if (stat_fd_ >= 0) close(stat_fd_);
  if (statm_fd_ >= 0) close(statm_fd_);
  if (status_fd_ >= 0) close(status_fd_);
}

ProcessSample ProcessSampler::Sample() const noexcept {
  ProcessSample s;
  char buf[1024];
  ProcStat st;
  // An exited process's files read as ESRCH (or, for a zombie, state Z with no memory).
  if (!ParseProcStat(PreadAll(stat_fd_, buf, sizeof buf), &st) || st.state == 'Z' ||
      st.state == 'X') {
    return s;
  }
  const std::string_view statm = PreadAll(statm_fd_, buf, sizeof buf);
  std::size_t pos = 0;
  std::uint64_t size = 0, resident = 0, shared = 0;
  if (!NextNumber(statm, &pos, &size) || !NextNumber(statm, &pos, &resident) ||
      !NextNumber(statm, &pos, &shared)) {
    return s;
  }
  s.alive = true;
  s.rss_bytes = resident * page_bytes_;
  s.rss_file_bytes = shared * page_bytes_;
  s.rss_anon_bytes = resident > shared ? (resident - shared) * page_bytes_ : 0;
  s.minor_faults = st.minor_faults;
  s.major_faults = st.major_faults;
  // "VmSwap:\t    1234 kB" (absent for kernel threads).
  char status[4096];
  const std::string_view text = PreadAll(status_fd_, status, sizeof status);
  const std::size_t at = text.find("VmSwap:");
  if (at != std::string_view::npos) {
    std::size_t p = at + 7;
    while (p < text.size() && (text[p] == ' ' || text[p] == '\t')) ++p;
    std::uint64_t kib = 0;
    if (NextNumber(text, &p, &kib)) s.swap_bytes = kib * 1024;
  }
  return s;
}

RusageSample SampleRusage() noexcept {
  RusageSample r;
  rusage u{};
  // ru_maxrss is in KiB on Linux.
  if (getrusage(RUSAGE_SELF, &u) == 0) {
    r.self_minor_faults = static_cast<std::uint64_t>(u.ru_minflt);
    r.self_major_faults = static_cast<std::uint64_t>(u.ru_majflt);
    r.self_max_rss_bytes = static_cast<std::uint64_t>(u.ru_maxrss) * 1024;
  }
  if (getrusage(RUSAGE_CHILDREN, &u) == 0) {
    r.children_minor_faults = static_cast<std::uint64_t>(u.ru_minflt);
    r.children_major_faults = static_cast<std::uint64_t>(u.ru_majflt);
    r.children_max_rss_bytes = static_cast<std::uint64_t>(u.ru_maxrss) * 1024;
  }
  return r;
}

}  // namespace zm
