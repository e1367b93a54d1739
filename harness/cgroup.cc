// Memory cgroup children for the device under test. See cgroup.h.
#include "harness/cgroup.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <utility>

#include "harness/control_file.h"
#include "harness/process_sample.h"
#include "runtime/budget.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

Result<std::string> ReadFile(const std::string& path) { return ReadControlFile(path, "cgroup"); }

// The error names the file, the value and, for byte limits, the limit in readable units.
Status WriteFile(const std::string& path, const std::string& value, std::string_view what = {}) {
  return WriteControlFile(path, value, "cgroup", what);
}

// Reads one unsigned number ("max" = no limit = UINT64_MAX).
Result<std::uint64_t> ReadNumber(const std::string& path) {
  ZM_ASSIGN_OR_RETURN(std::string text, ReadFile(path));
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  if (text == "max") return ~std::uint64_t{0};
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size()) {
    return Corrupt("cgroup: " + path + " holds '" + text + "', not a number");
  }
  return v;
}

// `key value` lines (memory.events, memory.oom_control): true and *out = the value of `key`.
bool FindKeyValue(std::string_view text, std::string_view key, std::uint64_t* out) noexcept {
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view line = text.substr(pos, eol - pos);
    if (line.size() > key.size() && line.substr(0, key.size()) == key && line[key.size()] == ' ') {
      const std::string_view num = line.substr(key.size() + 1);
      std::uint64_t v = 0;
      const auto [end, ec] = std::from_chars(num.data(), num.data() + num.size(), v);
      if (ec == std::errc()) {
        *out = v;
        return true;
      }
      return false;
    }
    pos = eol + 1;
  }
  return false;
}

std::string_view PreadAll(int fd, char* buf, std::size_t size) noexcept {
  if (fd < 0) return {};
  const ssize_t n = pread(fd, buf, size, 0);
  if (n <= 0) return {};
  return {buf, static_cast<std::size_t>(n)};
}

bool PreadNumber(int fd, std::uint64_t* out) noexcept {
  char buf[64];
  const std::string_view t = PreadAll(fd, buf, sizeof buf);
  if (t.empty()) return false;
  if (t.substr(0, 3) == "max") {
    *out = ~std::uint64_t{0};
    return true;
  }
  return std::from_chars(t.data(), t.data() + t.size(), *out).ec == std::errc();
}

// Splits on `sep`, yielding views.
template <class F>
void ForEachToken(std::string_view text, char sep, F&& f) {
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t end = text.find(sep, pos);
    if (end == std::string_view::npos) end = text.size();
    f(text.substr(pos, end - pos));
    pos = end + 1;
  }
}

bool HasToken(std::string_view text, char sep, std::string_view token) {
  bool found = false;
  ForEachToken(text, sep, [&](std::string_view t) {
    while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.remove_suffix(1);
    while (!t.empty() && t.front() == ' ') t.remove_prefix(1);
    if (t == token) found = true;
  });
  return found;
}

// mountinfo escapes space, tab, newline and backslash as \ooo.
std::string Unescape(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\\' && i + 3 < s.size()) {
      int v = 0;
      bool octal = true;
      for (std::size_t k = 1; k <= 3; ++k) {
        if (i + k >= s.size() || s[i + k] < '0' || s[i + k] > '7') {
          octal = false;
          break;
        }
        v = v * 8 + (s[i + k] - '0');
      }
      if (octal) {
        out.push_back(static_cast<char>(v));
        i += 3;
        continue;
      }
    }
    out.push_back(s[i]);
  }
  return out;
}

struct Mount {
  std::string root;  // the part of the hierarchy mounted there
  std::string mountpoint;
};

// The first mount of `fstype` whose super options contain `option` (empty: any).
bool FindMount(std::string_view mountinfo, std::string_view fstype, std::string_view option,
               Mount* out) {
  bool found = false;
  ForEachToken(mountinfo, '\n', [&](std::string_view line) {
    if (found || line.empty()) return;
    const std::size_t dash = line.find(" - ");
    if (dash == std::string_view::npos) return;
    std::string_view fields[5];
    std::size_t n = 0;
    ForEachToken(line.substr(0, dash), ' ', [&](std::string_view t) {
      if (n < 5) fields[n++] = t;
    });
    if (n < 5) return;
    std::string_view after[3];
    std::size_t m = 0;
    ForEachToken(line.substr(dash + 3), ' ', [&](std::string_view t) {
      if (m < 3) after[m++] = t;
    });
    if (m < 1 || after[0] != fstype) return;
    if (!option.empty() && (m < 3 || !HasToken(after[2], ',', option))) return;
    out->root = Unescape(fields[3]);
    out->mountpoint = Unescape(fields[4]);
    found = true;
  });
  return found;
}

Result<std::string> JoinMount(const Mount& mount, std::string_view path, std::string_view what) {
  std::string p(path);
  if (mount.root != "/") {
    if (p.compare(0, mount.root.size(), mount.root) != 0 ||
        (p.size() > mount.root.size() && p[mount.root.size()] != '/')) {
      return NotFound("cgroup: this process's " + std::string(what) + " cgroup " + p +
                      " is outside the part of the hierarchy mounted at " + mount.mountpoint +
                      " (" + mount.root + ")");
    }
    p = p.substr(mount.root.size());
  }
  if (p == "/") p.clear();
  return mount.mountpoint + p;
}

std::atomic<std::uint64_t> g_sequence{0};

std::string ChildName(std::string_view prefix) {
  const pid_t pid = getpid();
  return std::string(prefix) + "-" + std::to_string(pid) + "-" +
         std::to_string(ProcessStartTicks(pid)) + "-" + std::to_string(g_sequence.fetch_add(1));
}

Result<std::vector<pid_t>> ReadProcs(const std::string& dir) {
  ZM_ASSIGN_OR_RETURN(std::string text, ReadFile(dir + "/cgroup.procs"));
  std::vector<pid_t> pids;
  ForEachToken(text, '\n', [&](std::string_view t) {
    int v = 0;
    if (!t.empty() && std::from_chars(t.data(), t.data() + t.size(), v).ec == std::errc()) {
      pids.push_back(static_cast<pid_t>(v));
    }
  });
  return pids;
}

// Kills everything in `dir`, waits until it is empty, removes it.
Status KillAndRemove(const std::string& dir) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  const bool v2_kill = PathExists(dir + "/cgroup.kill");
  for (;;) {
    auto pids = ReadProcs(dir);
    if (!pids.ok()) {
      if (!PathExists(dir)) return Status::Ok();  // already gone
      return pids.status();
    }
    if (pids->empty()) break;
    if (std::chrono::steady_clock::now() > deadline) {
      return IoError("cgroup: " + std::to_string(pids->size()) + " process(es) still in " + dir +
                     " 10 s after SIGKILL (first: " + std::to_string(pids->front()) + ")");
    }
    if (v2_kill) {
      (void)WriteFile(dir + "/cgroup.kill", "1");
    } else {
      for (pid_t p : *pids) {
        if (p != getpid()) ::kill(p, SIGKILL);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // A process that has just left may still hold the directory busy for a moment.
  for (int attempt = 0;; ++attempt) {
    if (::rmdir(dir.c_str()) == 0 || errno == ENOENT) return Status::Ok();
    if (errno != EBUSY || attempt >= 200) {
      return IoError("cgroup: cannot remove " + dir + ": " + ErrnoText(errno));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

Result<std::uint64_t> MachineMemoryBytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::uint64_t kib = 0;
  while (in >> key >> kib) {
    if (key == "MemTotal:") return kib * 1024;
    in.ignore(1 << 10, '\n');
  }
  return NotFound("cgroup: /proc/meminfo has no MemTotal");
}

// The device must fit in every ancestor's limit and in the machine, or it would be smaller
// than the profile says without anyone noticing.
Status CheckRoomFor(const std::string& parent, CgroupVersion version, std::uint64_t limit,
                    const std::string& mountpoint) {
  const char* file = version == CgroupVersion::kV1 ? "memory.limit_in_bytes" : "memory.max";
  std::string dir = parent;
  while (dir.size() >= mountpoint.size() && !dir.empty()) {
    const std::string path = dir + "/" + file;
    if (PathExists(path)) {
      auto v = ReadNumber(path);
      if (v.ok() && *v < limit) {
        return FailedPrecondition("cgroup: the device limit " + FormatBytes(limit) +
                                  " exceeds the limit of an enclosing cgroup, " + path + " = " +
                                  FormatBytes(*v) + " (scale the device down: --device-scale)");
      }
    }
    if (dir == mountpoint) break;
    const std::size_t slash = dir.rfind('/');
    if (slash == std::string::npos || slash == 0) break;
    dir.resize(slash);
  }
  auto machine = MachineMemoryBytes();
  if (machine.ok() && *machine < limit) {
    return FailedPrecondition("cgroup: the device limit " + FormatBytes(limit) +
                              " exceeds this machine's memory (MemTotal " + FormatBytes(*machine) +
                              "; scale the device down: --device-scale)");
  }
  return Status::Ok();
}

int OpenRead(const std::string& path) { return open(path.c_str(), O_RDONLY | O_CLOEXEC); }

}  // namespace

std::string_view CgroupVersionName(CgroupVersion version) {
  return version == CgroupVersion::kV1 ? "v1" : "v2";
}

Result<CgroupLocation> LocateMemoryCgroup(std::string_view proc_cgroup,
                                          std::string_view mountinfo) {
  std::string v1_path, v2_path;
  bool v1 = false, v2 = false;
  ForEachToken(proc_cgroup, '\n', [&](std::string_view line) {
    // hierarchy-ID:controller-list:cgroup-path (the path may itself contain ':').
    const std::size_t a = line.find(':');
    if (a == std::string_view::npos) return;
    const std::size_t b = line.find(':', a + 1);
    if (b == std::string_view::npos) return;
    const std::string_view id = line.substr(0, a);
    const std::string_view controllers = line.substr(a + 1, b - a - 1);
    const std::string_view path = line.substr(b + 1);
    if (id == "0" && controllers.empty()) {
      v2 = true;
      v2_path = std::string(path);
    } else if (HasToken(controllers, ',', "memory")) {
      v1 = true;
      v1_path = std::string(path);
    }
  });
  Mount mount;
  if (v1) {
    if (!FindMount(mountinfo, "cgroup", "memory", &mount)) {
      return NotFound("cgroup: the v1 memory controller (" + v1_path +
                      " in /proc/self/cgroup) is not mounted (no cgroup mount with 'memory' in "
                      "/proc/self/mountinfo)");
    }
    ZM_ASSIGN_OR_RETURN(std::string dir, JoinMount(mount, v1_path, "memory"));
    return CgroupLocation{CgroupVersion::kV1, std::move(dir)};
  }
  if (v2) {
    if (!FindMount(mountinfo, "cgroup2", "", &mount)) {
      return NotFound("cgroup: the v2 hierarchy (" + v2_path +
                      " in /proc/self/cgroup) is not mounted (no cgroup2 in /proc/self/mountinfo)");
    }
    ZM_ASSIGN_OR_RETURN(std::string dir, JoinMount(mount, v2_path, "v2"));
    return CgroupLocation{CgroupVersion::kV2, std::move(dir)};
  }
  return NotFound("cgroup: /proc/self/cgroup has neither a v1 memory line nor a v2 '0::' line");
}

Result<CgroupLocation> LocateOwnMemoryCgroup() {
  ZM_ASSIGN_OR_RETURN(std::string cg, ReadFile("/proc/self/cgroup"));
  ZM_ASSIGN_OR_RETURN(std::string mi, ReadFile("/proc/self/mountinfo"));
  ZM_ASSIGN_OR_RETURN(CgroupLocation loc, LocateMemoryCgroup(cg, mi));
  if (loc.version == CgroupVersion::kV2) {
    ZM_ASSIGN_OR_RETURN(std::string controllers, ReadFile(loc.dir + "/cgroup.controllers"));
    if (!HasToken(controllers, ' ', "memory")) {
      return NotFound("cgroup: the v2 cgroup " + loc.dir +
                      " has no memory controller (cgroup.controllers: '" +
                      controllers.substr(0, controllers.find('\n')) + "')");
    }
  }
  return loc;
}

bool ParseCgroupChildName(std::string_view name, std::string_view prefix, CgroupChildName* out) {
  if (name.size() <= prefix.size() + 1 || name.substr(0, prefix.size()) != prefix ||
      name[prefix.size()] != '-') {
    return false;
  }
  std::string_view rest = name.substr(prefix.size() + 1);
  std::uint64_t parts[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    const auto [end, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), parts[i]);
    if (ec != std::errc() || end == rest.data()) return false;
    rest.remove_prefix(static_cast<std::size_t>(end - rest.data()));
    if (i < 2) {
      if (rest.empty() || rest.front() != '-') return false;
      rest.remove_prefix(1);
    }
  }
  if (!rest.empty() || parts[0] == 0 || parts[0] > 0x7FFFFFFF) return false;
  out->pid = static_cast<pid_t>(parts[0]);
  out->start_ticks = parts[1];
  out->sequence = parts[2];
  return true;
}

Result<std::uint32_t> RemoveStaleCgroups(const std::string& parent_dir, std::string_view prefix) {
  std::error_code ec;
  fs::directory_iterator it(parent_dir, ec);
  if (ec) return IoError("cgroup: cannot list " + parent_dir + ": " + ec.message());
  std::uint32_t removed = 0;
  Status first_error;
  for (const fs::directory_entry& e : it) {
    if (!e.is_directory(ec)) continue;
    const std::string name = e.path().filename().string();
    CgroupChildName parsed;
    if (!ParseCgroupChildName(name, prefix, &parsed)) continue;
    // Alive and the same process (not a reused pid): another run's, or ours.
    if (ProcessStartTicks(parsed.pid) == parsed.start_ticks) continue;
    Status s = KillAndRemove(e.path().string());
    if (s.ok()) {
      ++removed;
    } else if (first_error.ok()) {
      first_error = s.Annotate("removing a stale cgroup");
    }
  }
  if (!first_error.ok()) return first_error;
  return removed;
}

Result<Cgroup> Cgroup::Create(const CgroupOptions& options) {
  if (options.limit_bytes == 0) return InvalidArgument("cgroup: limit_bytes is 0");
  if (options.prefix.empty() || options.prefix.find('/') != std::string::npos) {
    return InvalidArgument("cgroup: prefix '" + options.prefix + "' must be a non-empty name");
  }
  CgroupLocation parent;
  std::string mountpoint;
  if (options.parent_dir.empty()) {
    ZM_ASSIGN_OR_RETURN(parent, LocateOwnMemoryCgroup());
  } else {
    parent.dir = options.parent_dir;
    parent.version =
        PathExists(parent.dir + "/cgroup.controllers") ? CgroupVersion::kV2 : CgroupVersion::kV1;
  }
  {
    // For the ancestor walk: stop at the hierarchy's mount point.
    auto mi = ReadFile("/proc/self/mountinfo");
    Mount m;
    if (mi.ok() && FindMount(*mi, parent.version == CgroupVersion::kV1 ? "cgroup" : "cgroup2",
                             parent.version == CgroupVersion::kV1 ? "memory" : "", &m)) {
      mountpoint = m.mountpoint;
    }
  }
  ZM_RETURN_IF_ERROR(CheckRoomFor(parent.dir, parent.version, options.limit_bytes,
                                  mountpoint.empty() ? parent.dir : mountpoint));

  if (parent.version == CgroupVersion::kV2) {
    // A v2 child gets the memory controller only if its parent hands it down; the kernel
    // refuses that (EBUSY) while the parent itself holds processes ("no internal processes").
    ZM_ASSIGN_OR_RETURN(std::string subtree, ReadFile(parent.dir + "/cgroup.subtree_control"));
    if (!HasToken(subtree, ' ', "memory")) {
      Status s = WriteFile(parent.dir + "/cgroup.subtree_control", "+memory");
      if (!s.ok()) {
        return FailedPrecondition(
            s.message() +
            " (cgroup v2 gives a child the memory controller only when its parent holds no "
            "processes: run in a delegated cgroup and pass it as the parent, e.g. a systemd "
            "scope with Delegate=yes)");
      }
    }
  }

  if (options.remove_stale) {
    auto stale = RemoveStaleCgroups(parent.dir, options.prefix);
    if (!stale.ok()) return stale.status();
  }

  Cgroup cg;
  cg.version_ = parent.version;
  const std::string dir = parent.dir + "/" + ChildName(options.prefix);
  if (::mkdir(dir.c_str(), 0755) != 0) {
    return IoError("cgroup: cannot create " + dir + ": " + ErrnoText(errno));
  }
  cg.dir_ = dir;  // from here on the destructor removes it

  const std::string value = std::to_string(options.limit_bytes);
  const std::string what = "the device limit, " + FormatBytes(options.limit_bytes);
  const std::string swap_what = "the device swap, " + FormatBytes(options.swap_bytes);
  if (cg.version_ == CgroupVersion::kV1) {
    ZM_RETURN_IF_ERROR(WriteFile(dir + "/memory.limit_in_bytes", value, what));
    // memsw = memory + swap, never below the memory limit (so it is written second). Equal to
    // the memory limit means no swap at all. Absent when the kernel does not account swap (then
    // swap cannot be limited: swap_limited = false).
    if (PathExists(dir + "/memory.memsw.limit_in_bytes")) {
      ZM_RETURN_IF_ERROR(WriteFile(dir + "/memory.memsw.limit_in_bytes",
                                   std::to_string(options.limit_bytes + options.swap_bytes),
                                   options.swap_bytes == 0 ? what : what + " + " + swap_what));
      cg.swap_limited_ = true;
      cg.swap_limit_bytes_ = options.swap_bytes;
      cg.swap_fd_ = OpenRead(dir + "/memory.memsw.usage_in_bytes");
    }
    if (options.swappiness >= 0 && PathExists(dir + "/memory.swappiness")) {
      ZM_RETURN_IF_ERROR(WriteFile(dir + "/memory.swappiness", std::to_string(options.swappiness),
                                   "the device's swappiness"));
    }
    ZM_ASSIGN_OR_RETURN(cg.limit_bytes_, ReadNumber(dir + "/memory.limit_in_bytes"));
    cg.current_limit_bytes_ = cg.limit_bytes_;
    cg.usage_fd_ = OpenRead(dir + "/memory.usage_in_bytes");
    cg.peak_fd_ = OpenRead(dir + "/memory.max_usage_in_bytes");
    cg.events_fd_ = OpenRead(dir + "/memory.oom_control");
    cg.failcnt_fd_ = OpenRead(dir + "/memory.failcnt");
    if (cg.swap_limited_) cg.memsw_failcnt_fd_ = OpenRead(dir + "/memory.memsw.failcnt");
  } else {
    ZM_RETURN_IF_ERROR(WriteFile(dir + "/memory.max", value, what));
    if (PathExists(dir + "/memory.swap.max")) {
      ZM_RETURN_IF_ERROR(WriteFile(dir + "/memory.swap.max", std::to_string(options.swap_bytes),
                                   options.swap_bytes == 0 ? "no swap" : swap_what));
      cg.swap_limited_ = true;
      cg.swap_limit_bytes_ = options.swap_bytes;
      cg.swap_fd_ = OpenRead(dir + "/memory.swap.current");
    }
    ZM_ASSIGN_OR_RETURN(cg.limit_bytes_, ReadNumber(dir + "/memory.max"));
    cg.current_limit_bytes_ = cg.limit_bytes_;
    cg.usage_fd_ = OpenRead(dir + "/memory.current");
    cg.peak_fd_ = OpenRead(dir + "/memory.peak");  // Linux >= 5.19; -1 before
    cg.events_fd_ = OpenRead(dir + "/memory.events");
  }
  if (cg.usage_fd_ < 0 || cg.events_fd_ < 0) {
    return IoError("cgroup: cannot open the counters of " + dir + ": " + ErrnoText(errno));
  }
  cg.procs_fd_ = open((dir + "/cgroup.procs").c_str(), O_WRONLY | O_CLOEXEC);
  if (cg.procs_fd_ < 0) {
    return IoError("cgroup: cannot open " + dir + "/cgroup.procs: " + ErrnoText(errno));
  }
  return cg;
}

Cgroup::Cgroup(Cgroup&& other) noexcept { *this = std::move(other); }

Cgroup& Cgroup::operator=(Cgroup&& other) noexcept {
  if (this != &other) {
    (void)Remove();
    dir_ = std::exchange(other.dir_, {});
    version_ = other.version_;
    limit_bytes_ = std::exchange(other.limit_bytes_, 0);
    current_limit_bytes_ = std::exchange(other.current_limit_bytes_, 0);
    sampled_peak_ = std::exchange(other.sampled_peak_, 0);
    swap_limited_ = std::exchange(other.swap_limited_, false);
    swap_limit_bytes_ = std::exchange(other.swap_limit_bytes_, 0);
    swap_fd_ = std::exchange(other.swap_fd_, -1);
    procs_fd_ = std::exchange(other.procs_fd_, -1);
    usage_fd_ = std::exchange(other.usage_fd_, -1);
    peak_fd_ = std::exchange(other.peak_fd_, -1);
    events_fd_ = std::exchange(other.events_fd_, -1);
    failcnt_fd_ = std::exchange(other.failcnt_fd_, -1);
    memsw_failcnt_fd_ = std::exchange(other.memsw_failcnt_fd_, -1);
  }
  return *this;
}

Cgroup::~Cgroup() { (void)Remove(); }

void Cgroup::CloseFiles() noexcept {
  for (int* fd : {&procs_fd_, &usage_fd_, &peak_fd_, &events_fd_, &failcnt_fd_, &memsw_failcnt_fd_,
                  &swap_fd_}) {
    if (*fd >= 0) close(*fd);
    *fd = -1;
  }
}

Status Cgroup::SetMemoryLimit(std::uint64_t bytes) {
  if (!active()) return FailedPrecondition("cgroup: SetMemoryLimit on a removed cgroup");
  if (bytes == 0 || bytes > limit_bytes_) {
    return InvalidArgument("cgroup: memory limit " + FormatBytes(bytes) +
                           " is outside (0, the device limit " + FormatBytes(limit_bytes_) + "]");
  }
  if (bytes == current_limit_bytes_) return Status::Ok();
  const char* file = version_ == CgroupVersion::kV1 ? "/memory.limit_in_bytes" : "/memory.max";
  ZM_RETURN_IF_ERROR(WriteFile(dir_ + file, std::to_string(bytes),
                               "the device limit less what zram holds, " + FormatBytes(bytes)));
  current_limit_bytes_ = bytes;
  return Status::Ok();
}

std::uint64_t ChargedLimit(std::uint64_t limit_bytes, std::uint64_t outside_bytes,
                           std::uint64_t granularity_bytes, std::uint64_t floor_bytes) noexcept {
  const std::uint64_t g = granularity_bytes == 0 ? 1 : granularity_bytes;
  const std::uint64_t outside = outside_bytes == 0 ? 0 : (outside_bytes + g - 1) / g * g;
  const std::uint64_t floor = std::min(floor_bytes, limit_bytes);
  return outside >= limit_bytes - floor ? floor : limit_bytes - outside;
}

Status Cgroup::AddProcess(pid_t pid) const {
  if (!active()) return FailedPrecondition("cgroup: AddProcess on a removed cgroup");
  return WriteFile(dir_ + "/cgroup.procs", std::to_string(pid), "a process id");
}

int Cgroup::EnterSelf() const noexcept {
  if (procs_fd_ < 0) return EBADF;
  // "0" is the writing process itself, in v1 and v2 alike.
  return write(procs_fd_, "0", 1) == 1 ? 0 : errno;
}

CgroupSample Cgroup::Sample() noexcept {
  CgroupSample s;
  bool ok = PreadNumber(usage_fd_, &s.usage_bytes);
  if (ok && s.usage_bytes > sampled_peak_) sampled_peak_ = s.usage_bytes;
  std::uint64_t kernel_peak = 0;
  s.peak_bytes = (peak_fd_ >= 0 && PreadNumber(peak_fd_, &kernel_peak))
                     ? std::max(kernel_peak, sampled_peak_)
                     : sampled_peak_;
  char buf[512];
  const std::string_view events = PreadAll(events_fd_, buf, sizeof buf);
  ok = ok && FindKeyValue(events, "oom_kill", &s.oom_kills);
  std::uint64_t swap_or_memsw = 0;
  if (PreadNumber(swap_fd_, &swap_or_memsw)) {
    // v1 reads memory + swap: the swap is the difference (read after usage: clamp at 0).
    s.swap_bytes = version_ == CgroupVersion::kV2  ? swap_or_memsw
                   : swap_or_memsw > s.usage_bytes ? swap_or_memsw - s.usage_bytes
                                                   : 0;
  }
  if (version_ == CgroupVersion::kV1) {
    std::uint64_t under = 0;
    if (FindKeyValue(events, "under_oom", &under)) s.under_oom = under != 0;
    std::uint64_t memory_hits = 0, memsw_hits = 0;
    (void)PreadNumber(failcnt_fd_, &memory_hits);
    (void)PreadNumber(memsw_failcnt_fd_, &memsw_hits);
    s.limit_hits = memory_hits + memsw_hits;
  } else {
    (void)FindKeyValue(events, "max", &s.limit_hits);
  }
  s.ok = ok;
  return s;
}

Result<std::vector<pid_t>> Cgroup::Processes() const {
  if (!active()) return FailedPrecondition("cgroup: Processes on a removed cgroup");
  return ReadProcs(dir_);
}

Status Cgroup::Remove() {
  if (!active()) return Status::Ok();
  CloseFiles();
  Status s = KillAndRemove(dir_);
  dir_.clear();
  return s;
}

}  // namespace zm
