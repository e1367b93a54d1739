// The co-tenant as a child process: spawning zonemap-cotenant with a pipe for its event lines
// and a socket for its commands, reading lines, reaping and classifying its end. See cotenant.h.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>
#include <utility>

#include "harness/cotenant.h"
#include "harness/device_model.h"

extern char** environ;

namespace zm {
namespace {

std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

std::vector<std::string> CotenantCommandLine(const CotenantConfig& c, bool serve) {
  const CotenantOptions& o = c.options;
  // Flag and value pairs, one pair a line.
  // clang-format off
  std::vector<std::string> a = {
      "--model",          c.model,
      "--device-scale",   Num(c.device_scale),
      "--prompt-tokens",  std::to_string(o.prompt_tokens),
      "--answer-tokens",  std::to_string(o.answer_tokens),
      "--prompt-batch",   std::to_string(o.prompt_batch_tokens),
      "--context-tokens", std::to_string(o.context_tokens),
      "--requests",       std::to_string(c.requests),
      "--period-s",       Num(o.request_period_s),
      "--watchdog-s",     Num(o.watchdog_s),
      "--kv-allocation",  std::string(KvAllocationName(o.kv_allocation)),
      "--weights",        std::string(CotenantWeightsName(o.weights)),
      o.prefetch ? "--prefetch" : "--no-prefetch",
      o.cold_start ? "--cold-start" : "--no-cold-start",
      "--jsonl",
  };
  // clang-format on
  if (serve) a.emplace_back("--serve");
  if (c.weights_bytes != 0) a.insert(a.end(), {"--weights-bytes", std::to_string(c.weights_bytes)});
  if (o.kv_bytes_per_token != 0) {
    a.insert(a.end(), {"--kv-bytes-per-token", std::to_string(o.kv_bytes_per_token)});
  }
  if (!o.weights_dir.empty()) a.insert(a.end(), {"--weights-dir", o.weights_dir});
  if (!c.ledger_path.empty()) {
    a.insert(a.end(), {"--ledger", c.ledger_path});
    if (c.ledger_device_bytes != 0) {
      a.insert(a.end(), {"--ledger-device-bytes", std::to_string(c.ledger_device_bytes)});
    }
  }
  if (!c.ledger_name.empty()) a.insert(a.end(), {"--ledger-name", c.ledger_name});
  return a;
}

std::string FindCotenantExecutable() {
  if (const char* env = std::getenv("ZM_COTENANT_EXE"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto dir = exe.parent_path();
    for (const auto& candidate : {dir / "zonemap-cotenant", dir / ".." / "app" / "zonemap-cotenant",
                                  dir / ".." / ".." / "app" / "zonemap-cotenant"}) {
      if (std::filesystem::is_regular_file(candidate, ec)) return candidate.lexically_normal();
    }
  }
  return "zonemap-cotenant";
}

CotenantExit ClassifyCotenantExit(int status) {
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    return {sig == SIGKILL ? "killed" : "crashed", sig};
  }
  return {"exited", WIFEXITED(status) ? WEXITSTATUS(status) : 0};
}

// ---- CotenantProcess ----

CotenantProcess::CotenantProcess(CotenantProcess&& o) noexcept
    : pid_(std::exchange(o.pid_, -1)),
      out_fd_(std::exchange(o.out_fd_, -1)),
      in_fd_(std::exchange(o.in_fd_, -1)),
      partial_(std::move(o.partial_)),
      spawned_mono_s_(o.spawned_mono_s_) {}

CotenantProcess& CotenantProcess::operator=(CotenantProcess&& o) noexcept {
  if (this != &o) {
    Reset();
    pid_ = std::exchange(o.pid_, -1);
    out_fd_ = std::exchange(o.out_fd_, -1);
    in_fd_ = std::exchange(o.in_fd_, -1);
    partial_ = std::move(o.partial_);
    spawned_mono_s_ = o.spawned_mono_s_;
  }
  return *this;
}

CotenantProcess::~CotenantProcess() { Reset(); }

void CotenantProcess::Reset() noexcept {
  if (pid_ > 0) {
    kill(pid_, SIGTERM);
    if (in_fd_ >= 0) shutdown(in_fd_, SHUT_WR);
    (void)Reap(5.0);
  }
  if (out_fd_ >= 0) close(out_fd_);
  if (in_fd_ >= 0) close(in_fd_);
  out_fd_ = -1;
  in_fd_ = -1;
  partial_.clear();
}

Result<CotenantProcess> CotenantProcess::Spawn(const CotenantConfig& config, std::string executable,
                                               bool serve, const DeviceModel* device) {
  if (executable.empty()) executable = FindCotenantExecutable();
  // ZM_COTENANT_LAUNCHER (space-separated, e.g. "qemu-aarch64 -L /sysroot") runs the program
  // through an emulator when the kernel cannot execute it directly.
  std::vector<std::string> args;
  if (const char* l = std::getenv("ZM_COTENANT_LAUNCHER"); l != nullptr && *l != '\0') {
    const std::string launcher(l);
    std::size_t pos = 0;
    while (pos < launcher.size()) {
      const std::size_t end = launcher.find(' ', pos);
      std::string word = launcher.substr(pos, end == std::string::npos ? end : end - pos);
      if (!word.empty()) args.push_back(std::move(word));
      if (end == std::string::npos) break;
      pos = end + 1;
    }
  }
  args.push_back(executable);
  for (std::string& a : CotenantCommandLine(config, serve)) args.push_back(std::move(a));

  int out[2];
  if (pipe2(out, O_CLOEXEC) != 0) return IoError(std::string("pipe: ") + std::strerror(errno));
  int in[2];
  if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, in) != 0) {
    const int e = errno;
    close(out[0]);
    close(out[1]);
    return IoError(std::string("socketpair: ") + std::strerror(e));
  }
  pid_t pid = -1;
  Status spawn_error;
  if (device == nullptr) {
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, in[1], STDIN_FILENO);
    const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) spawn_error = IoError(std::strerror(rc));
  } else {
    // The device's one fork protocol: the child enters it before exec, or it is reaped and the
    // error says why (a failed start, like a program that cannot be executed).
    // Copy-constructed: GCC 12 -O3 (aarch64) warns of a null dereference, falsely, inside a
    // vector<string> copy assignment here.
    const SpawnRequest request{.argv = args, .stdin_fd = in[1], .stdout_fd = out[1]};
    Result<pid_t> spawned = SpawnInDevice(request, *device);
    if (spawned.ok()) {
      pid = *spawned;
    } else {
      spawn_error = spawned.status();
    }
  }
  close(out[1]);
  close(in[1]);
  if (!spawn_error.ok()) {
    close(out[0]);
    close(in[0]);
    return IoError("cannot start the co-tenant stand-in '" + args.front() +
                   "': " + spawn_error.message());
  }
  CotenantProcess p;
  p.spawned_mono_s_ = MonotonicSeconds();
  p.pid_ = pid;
  p.out_fd_ = out[0];
  p.in_fd_ = in[0];
  return p;
}

void CotenantProcess::RequestStop() noexcept {
  if (pid_ > 0) kill(pid_, SIGTERM);
}

bool CotenantProcess::SendLine(std::string_view line) noexcept {
  if (in_fd_ < 0) return false;
  std::string s(line);
  s.push_back('\n');
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = send(in_fd_, s.data() + done, s.size() - done, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

bool CotenantProcess::ReadLines(std::vector<std::string>& lines, int timeout_ms) {
  if (out_fd_ < 0) return false;
  pollfd p{out_fd_, POLLIN, 0};
  const int r = poll(&p, 1, timeout_ms);
  if (r <= 0) return true;  // timeout (or EINTR): nothing yet
  char buf[16384];
  const ssize_t n = read(out_fd_, buf, sizeof buf);
  if (n < 0) return errno == EINTR || errno == EAGAIN;
  if (n == 0) {
    if (!partial_.empty()) lines.push_back(std::exchange(partial_, {}));
    return false;
  }
  partial_.append(buf, static_cast<std::size_t>(n));
  std::size_t start = 0;
  for (std::size_t nl; (nl = partial_.find('\n', start)) != std::string::npos; start = nl + 1) {
    if (nl > start) lines.push_back(partial_.substr(start, nl - start));
  }
  partial_.erase(0, start);
  return true;
}

int CotenantProcess::Reap(double timeout_s) {
  if (pid_ <= 0) return 0;
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == pid_) break;
    if (r < 0 && errno != EINTR) break;
    if (std::chrono::steady_clock::now() >= deadline) {
      kill(pid_, SIGKILL);
      while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  pid_ = -1;
  return status;
}

Result<CotenantResult> CotenantProcess::Wait() {
  if (pid_ <= 0) return FailedPrecondition("the co-tenant stand-in process is not running");
  CotenantReportBuilder builder(spawned_mono_s_);
  const pid_t pid = pid_;
  (void)builder.Add({{"event", "spawn"}, {"instance", 0}, {"pid", pid}});
  std::vector<std::string> lines;
  bool open = true;
  while (open) {
    open = ReadLines(lines, -1);
    for (const std::string& l : lines) {
      if (Status s = builder.AddLine(l); !s.ok())
        return s.Annotate("co-tenant pid " + std::to_string(pid));
    }
    lines.clear();
  }
  const CotenantExit exit = ClassifyCotenantExit(Reap(5.0));
  (void)builder.Add(
      {{"event", "exit"}, {"kind", std::string(exit.kind)}, {"code", exit.code}, {"pid", pid}});
  return builder.Report();
}

}  // namespace zm
