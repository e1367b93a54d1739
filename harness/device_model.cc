// The device under test: a memory cgroup, or the ledger standing in for one. See device_model.h.
#include "harness/device_model.h"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <utility>

#include "runtime/budget.h"

namespace zm {
namespace {

class CgroupDevice final : public DeviceModel {
 public:
  CgroupDevice(DeviceSwap swap, Cgroup cgroup)
      : swap_(std::move(swap)), cgroup_(std::move(cgroup)) {}
  ~CgroupDevice() override { (void)Remove(); }

  DeviceKind kind() const noexcept override { return DeviceKind::kCgroup; }
  std::uint64_t limit_bytes() const noexcept override { return cgroup_.limit_bytes(); }
  std::string Describe() const override {
    return "cgroup " + std::string(CgroupVersionName(cgroup_.version())) + " " + cgroup_.dir() +
           ", limit " + FormatBytes(cgroup_.limit_bytes()) +
           (!cgroup_.swap_limited() ? ", swap not accounted by this kernel"
            : cgroup_.swap_limit_bytes() == 0
                ? ", no swap: " + swap_.reason()
                : ", swap " + FormatBytes(cgroup_.swap_limit_bytes()) + " on " + swap_.Describe());
  }
  Status AddProcess(pid_t pid) override { return cgroup_.AddProcess(pid); }
  int EnterSelf() const noexcept override { return cgroup_.EnterSelf(); }
  DeviceSample Sample() noexcept override {
    const CgroupSample c = cgroup_.Sample();
    DeviceSample s;
    s.usage_bytes = c.usage_bytes;
    s.peak_bytes = c.peak_bytes;
    s.oom_kills = c.oom_kills;
    s.limit_hits = c.limit_hits;
    s.swap_bytes = c.swap_bytes;
    s.under_oom = c.under_oom;
    s.ok = c.ok;
    return s;
  }
  // The cgroup first (its processes killed, their swap entries freed), then the swap.
  Status Remove() override {
    Status c = cgroup_.Remove();
    Status w = swap_.Remove();
    return !c.ok() ? c : w;
  }
  const DeviceSwap& swap() const noexcept override { return swap_; }
  Cgroup* cgroup() noexcept override { return &cgroup_; }

 private:
  DeviceSwap swap_;  // declared first: destroyed after the cgroup
  Cgroup cgroup_;
};

class LedgerDevice final : public DeviceModel {
 public:
  LedgerDevice(DeviceLedger ledger, std::string reason) : ledger_(std::move(ledger)) {
    fallback_reason_ = std::move(reason);
  }
  ~LedgerDevice() override { (void)Remove(); }

  DeviceKind kind() const noexcept override { return DeviceKind::kLedger; }
  std::uint64_t limit_bytes() const noexcept override {
    return ledger_ ? ledger_->device_bytes() : 0;
  }
  std::string Describe() const override {
    std::string d = "ledger " + path_ + ", " + FormatBytes(limit_bytes()) +
                    " (simulated: out of memory is a refused grant, not the kernel's)";
    if (!fallback_reason_.empty()) d += "; no cgroup: " + fallback_reason_;
    return d;
  }
  Status AddProcess(pid_t) override { return Status::Ok(); }
  int EnterSelf() const noexcept override { return 0; }
  DeviceSample Sample() noexcept override {
    DeviceSample s;
    if (!ledger_) return s;
    s.usage_bytes = ledger_->sum_bytes();
    s.peak_bytes = ledger_->peak_sum_bytes();
    s.oom_kills = ledger_->oom_events();
    s.limit_hits = s.oom_kills;
    s.under_oom = ledger_->OverCommitted();
    s.ok = true;
    return s;
  }
  Status Remove() override {
    if (!ledger_) return Status::Ok();
    ledger_.reset();
    return DeviceLedger::Remove(path_);
  }
  DeviceLedger* ledger() noexcept override { return ledger_ ? &*ledger_ : nullptr; }

  void set_path(std::string path) { path_ = std::move(path); }

 private:
  std::optional<DeviceLedger> ledger_;
  std::string path_;
};

// What the child reports through the close-on-exec pipe when it fails before exec.
constexpr int kStageEnter = 1;  // entering the device
constexpr int kStageExec = 2;   // redirecting its standard streams, or exec
struct ChildFailure {
  int stage = 0;  // kStageEnter or kStageExec
  int err = 0;
};

[[noreturn]] void ReportAndExit(int fd, int stage, int err) noexcept {
  const ChildFailure f{stage, err};
  (void)!write(fd, &f, sizeof f);
  _exit(127);
}

// Reads the child's failure report; false when the pipe closed empty (exec happened, or the
// forked child is running inside the device).
bool ReadFailure(int fd, ChildFailure* f) {
  for (;;) {
    const ssize_t n = read(fd, f, sizeof *f);
    if (n < 0 && errno == EINTR) continue;
    return n == static_cast<ssize_t>(sizeof *f);
  }
}

// The one fork protocol of SpawnInDevice and ForkInDevice. fork(); the child enters `device`
// first, then runs in_child(report_fd), which either never returns (exec, or
// ReportAndExit(report_fd, kStageExec, errno) when that fails) or returns to go on as the
// caller's child (0 returned in it). The parent reads the close-on-exec pipe: empty means the
// child is inside (and exec'd, if it meant to); a report means it has exited 127 and is reaped
// here, and the error names `what` and the stage. in_child must be async-signal-safe.
template <typename InChild>
Result<pid_t> ForkReporting(const DeviceModel& device, const std::string& what,
                            InChild&& in_child) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) return IoError(what + ": pipe: " + std::strerror(errno));
  const pid_t pid = fork();
  if (pid < 0) {
    const int err = errno;
    close(fds[0]);
    close(fds[1]);
    return IoError(what + ": fork: " + std::strerror(err));
  }
  if (pid == 0) {
    close(fds[0]);
    const int err = device.EnterSelf();
    if (err != 0) ReportAndExit(fds[1], kStageEnter, err);
    in_child(fds[1]);
    close(fds[1]);  // empty: inside
    return pid_t{0};
  }
  close(fds[1]);
  ChildFailure f;
  const bool failed = ReadFailure(fds[0], &f);
  close(fds[0]);
  if (!failed) return pid;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (f.stage == kStageEnter) {
    return IoError(what + ": the child could not enter the device (" + device.Describe() +
                   "): " + std::strerror(f.err));
  }
  return IoError(what + ": cannot execute it: " + std::strerror(f.err));
}

}  // namespace

std::string_view DeviceKindName(DeviceKind kind) {
  return kind == DeviceKind::kCgroup ? "cgroup" : "ledger";
}

Result<DeviceKind> ParseDeviceKind(std::string_view text) {
  if (text == "cgroup") return DeviceKind::kCgroup;
  if (text == "ledger") return DeviceKind::kLedger;
  return InvalidArgument("--device '" + std::string(text) + "': expected cgroup or ledger");
}

Result<std::unique_ptr<DeviceModel>> OpenDeviceModel(const DeviceModelOptions& options) {
  if (options.limit_bytes == 0) return InvalidArgument("device: limit_bytes is 0");
  std::string reason;
  if (options.kind == DeviceKind::kCgroup) {
    // Stale cgroups first: a crashed run's processes may hold pages in its stale zram device,
    // which swapoff would have to bring back into their cgroup.
    if (options.cgroup.remove_stale) {
      Result<CgroupLocation> parent = options.cgroup.parent_dir.empty()
                                          ? LocateOwnMemoryCgroup()
                                          : Result<CgroupLocation>(CgroupLocation{
                                                CgroupVersion::kV1, options.cgroup.parent_dir});
      if (parent.ok()) (void)RemoveStaleCgroups(parent->dir, options.cgroup.prefix);
    }
    DeviceSwap swap = OpenDeviceSwap(options.swap);
    CgroupOptions co = options.cgroup;
    co.limit_bytes = options.limit_bytes;
    co.swap_bytes = swap.bytes();
    auto cg = Cgroup::Create(co);
    if (cg.ok()) {
      return std::unique_ptr<DeviceModel>(new CgroupDevice(std::move(swap), std::move(cg).value()));
    }
    if (!options.fall_back_to_ledger) return cg.status();
    reason = cg.status().message();
  }
  const std::string path =
      options.ledger_path.empty()
          ? DeviceLedger::DefaultLedgerPath() + "-" + std::to_string(static_cast<long>(getpid()))
          : options.ledger_path;
  (void)DeviceLedger::Remove(path);  // a fresh device every run
  ZM_ASSIGN_OR_RETURN(DeviceLedger ledger, DeviceLedger::Open(path, options.limit_bytes));
  auto device = std::make_unique<LedgerDevice>(std::move(ledger), std::move(reason));
  device->set_path(path);
  return std::unique_ptr<DeviceModel>(std::move(device));
}

Result<pid_t> SpawnInDevice(const SpawnRequest& request, const DeviceModel& device) {
  if (request.argv.empty()) return InvalidArgument("spawn: empty command line");
  // Everything the child needs is built before fork: after it, only async-signal-safe calls.
  std::vector<char*> argv;
  argv.reserve(request.argv.size() + 1);
  for (const std::string& a : request.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  return ForkReporting(device, "spawn " + request.argv[0], [&](int report_fd) noexcept {
    const std::pair<int, int> redirects[] = {{request.stdin_fd, STDIN_FILENO},
                                             {request.stdout_fd, STDOUT_FILENO},
                                             {request.stderr_fd, STDERR_FILENO}};
    for (const auto& [from, to] : redirects) {
      if (from >= 0 && dup2(from, to) < 0) ReportAndExit(report_fd, kStageExec, errno);
    }
    execvp(argv[0], argv.data());
    ReportAndExit(report_fd, kStageExec, errno);
  });
}

Result<pid_t> ForkInDevice(const DeviceModel& device) {
  return ForkReporting(device, "fork in the device", [](int) noexcept {});
}

ChildExit DescribeWaitStatus(int wait_status) noexcept {
  ChildExit e;
  if (WIFEXITED(wait_status)) {
    e.exited = true;
    e.code = WEXITSTATUS(wait_status);
  } else if (WIFSIGNALED(wait_status)) {
    e.signaled = true;
    e.signal = WTERMSIG(wait_status);
  }
  return e;
}

}  // namespace zm
