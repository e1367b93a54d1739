// The co-tenant supervisor: spawn, place, pace, watch, restart, aggregate. See
// cotenant_supervisor.h.
#include "harness/cotenant_supervisor.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>

#include "harness/weights_file.h"

namespace zm {

std::function<Status(pid_t)> PlaceInCgroupProcs(std::string procs_path) {
  return [path = std::move(procs_path)](pid_t pid) -> Status {
    const int fd = open(path.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0) return IoError("cannot open '" + path + "': " + std::strerror(errno));
    const std::string text = std::to_string(pid) + "\n";
    const ssize_t n = write(fd, text.data(), text.size());
    const int e = errno;
    close(fd);
    if (n != static_cast<ssize_t>(text.size())) {
      return IoError("writing pid " + std::to_string(pid) + " to '" + path +
                     "': " + std::strerror(n < 0 ? e : EIO));
    }
    return Status::Ok();
  };
}

CotenantSupervisor::~CotenantSupervisor() {
  if (thread_.joinable()) (void)Stop();
  if (wake_fd_ >= 0) close(wake_fd_);
}

Status CotenantSupervisor::Start(CotenantSupervisorOptions options) {
  if (thread_.joinable()) return FailedPrecondition("the co-tenant supervisor is already running");
  ZM_RETURN_IF_ERROR(ResolveCotenantSizes(options.config).status());
  if (!(options.restart_delay_s >= 0.0) || !(options.request_period_s >= 0.0)) {
    return InvalidArgument("co-tenant supervisor: restart delay and request period must be >= 0");
  }
  options_ = std::move(options);
  if (wake_fd_ < 0) wake_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake_fd_ < 0) return IoError(std::string("eventfd: ") + std::strerror(errno));
  if (!options_.events_path.empty()) {
    events_ = std::fopen(options_.events_path.c_str(), "a");
    if (events_ == nullptr) {
      return IoError("cannot open co-tenant events file '" + options_.events_path +
                     "': " + std::strerror(errno));
    }
  }
  t0_ = MonotonicSeconds();
  {
    std::lock_guard<std::mutex> lock(mu_);
    builder_ = CotenantReportBuilder(t0_);
  }
  // The weights file is made here, outside the device: writing it is a one-off cost of the
  // machine, not of the co-tenant's memory (a child creating it inside a tight cgroup would be
  // charged its dirty pages). A failure is left for the child to meet and report as ×.
  if (Result<CotenantSizes> sizes = ResolveCotenantSizes(options_.config); sizes.ok()) {
    if (Result<WeightsFileInfo> f =
            EnsureWeightsFile(options_.config.options.weights_dir, sizes->weights_bytes);
        f.ok()) {
      Record({{"event", "weights_file"},
              {"weights_path", f->path},
              {"weights_file_created", f->created},
              {"weights_create_ms", f->create_ms},
              {"weights_fs", f->fs_type}});
    }
  }
  quit_.store(false);
  try {
    thread_ = std::thread([this] { Loop(); });
  } catch (const std::system_error& e) {
    return ResourceExhausted(std::string("co-tenant supervisor thread: ") + e.what());
  }
  return Status::Ok();
}

std::uint64_t CotenantSupervisor::SubmitRequest() {
  const std::uint64_t id = next_id_.fetch_add(1);
  {
    std::lock_guard<std::mutex> lock(mu_);
    submitted_.emplace_back(id, MonotonicSeconds());
  }
  Wake();
  return id;
}

CotenantResult CotenantSupervisor::Snapshot() const {
  std::lock_guard<std::mutex> lock(mu_);
  return builder_.Report();
}

Result<CotenantResult> CotenantSupervisor::Stop() {
  if (!thread_.joinable()) return FailedPrecondition("the co-tenant supervisor is not running");
  quit_.store(true);
  Wake();
  thread_.join();
  if (events_ != nullptr) {
    std::fclose(events_);
    events_ = nullptr;
  }
  return Snapshot();
}

void CotenantSupervisor::Wake() {
  if (wake_fd_ < 0) return;
  const std::uint64_t one = 1;
  (void)!write(wake_fd_, &one, sizeof one);
}

void CotenantSupervisor::Record(nlohmann::json e) {
  e["stand_in"] = true;
  e["source"] = "supervisor";
  e["mono_s"] = MonotonicSeconds();
  const std::string line = e.dump();
  {
    std::lock_guard<std::mutex> lock(mu_);
    (void)builder_.Add(e);
  }
  if (events_ != nullptr) {
    std::fprintf(events_, "%s\n", line.c_str());
    std::fflush(events_);
  }
}

void CotenantSupervisor::Line(const std::string& line) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (Status s = builder_.AddLine(line); !s.ok()) {
      std::fprintf(stderr, "co-tenant supervisor: %s\n", s.message().c_str());
    }
  }
  if (events_ != nullptr) {
    std::fprintf(events_, "%s\n", line.c_str());
    std::fflush(events_);
  }
}

void CotenantSupervisor::Loop() {
  const CotenantSupervisorOptions& o = options_;
  std::optional<CotenantProcess> child;
  std::uint32_t instance = 0;  // of the current (or next) child
  double restart_at = t0_;
  std::uint64_t scheduled = 0;           // paced requests issued so far
  std::map<std::uint64_t, double> open;  // sent to the current child, not yet answered
  std::vector<std::string> lines;

  auto reap = [&](bool stopping) {
    const pid_t pid = child->pid();
    const CotenantExit exit = ClassifyCotenantExit(child->Reap(stopping ? 10.0 : 5.0));
    child.reset();
    child_pid_.store(-1);
    Record({{"event", "exit"},
            {"instance", instance},
            {"pid", pid},
            {"kind", stopping ? std::string("stopped") : std::string(exit.kind)},
            {"code", exit.code}});
    const std::string why = stopping
                                ? "in flight or queued when the run was stopped"
                                : "lost: the co-tenant " + std::string(exit.kind) +
                                      (exit.kind == "exited" ? " with status " : " by signal ") +
                                      std::to_string(exit.code);
    for (const auto& [id, submitted] : open) {
      Record({{"event", "request_failed"},
              {"id", id},
              {"pid", pid},
              {"submitted_s", submitted},
              {"unfinished", stopping},
              {"reason", why}});
    }
    open.clear();
    ++instance;
    restart_at = MonotonicSeconds() + o.restart_delay_s;
  };
  auto drain = [&](int timeout_ms) {
    lines.clear();
    const bool more = child->ReadLines(lines, timeout_ms);
    for (const std::string& l : lines) {
      const nlohmann::json j = nlohmann::json::parse(l, nullptr, false);
      if (j.is_object() && j.contains("id") && j["id"].is_number_unsigned()) {
        const std::string ev = j.value("event", std::string());
        if (ev == "request" || ev == "request_failed") open.erase(j["id"].get<std::uint64_t>());
      }
      Line(l);
    }
    return more;
  };
  auto submit = [&](std::uint64_t id, double submitted) {
    char cmd[96];
    std::snprintf(cmd, sizeof cmd, "request %llu %.9f", static_cast<unsigned long long>(id),
                  submitted);
    if (child && child->SendLine(cmd)) {
      open.emplace(id, submitted);
      return;
    }
    Record({{"event", "request_failed"},
            {"id", id},
            {"submitted_s", submitted},
            {"reason", "the co-tenant was not running (restart pending)"}});
  };

  while (!quit_.load()) {
    double now = MonotonicSeconds();
    if (!child && now >= restart_at && (o.max_restarts == 0 || instance <= o.max_restarts)) {
      Result<CotenantProcess> spawned =
          CotenantProcess::Spawn(o.config, o.executable, /*serve=*/true, o.device);
      Record({{"event", "spawn"},
              {"instance", instance},
              {"pid", spawned.ok() ? spawned->pid() : -1}});
      instances_.store(instance + 1);
      if (!spawned.ok()) {
        Record({{"event", "failed_to_start"}, {"reason", spawned.status().message()}});
        ++instance;
        restart_at = now + o.restart_delay_s;
      } else {
        child.emplace(std::move(spawned).value());
        child_pid_.store(child->pid());
        Status placed = o.place_child ? o.place_child(child->pid()) : Status::Ok();
        if (!placed.ok()) {
          kill(child->pid(), SIGKILL);
          (void)child->Reap(5.0);
          child.reset();
          child_pid_.store(-1);
          Record({{"event", "failed_to_start"},
                  {"reason", "placing the co-tenant in the device failed: " + placed.message()}});
          ++instance;
          restart_at = now + o.restart_delay_s;
        } else {
          (void)child->SendLine("start");
        }
      }
    }
    // The schedule is the same for every run: request i at t0 + i * period.
    while (o.request_period_s > 0.0 && (o.max_requests == 0 || scheduled < o.max_requests)) {
      const double due = t0_ + static_cast<double>(scheduled) * o.request_period_s;
      if (due > now) break;
      ++scheduled;
      submit(next_id_.fetch_add(1), due);
    }
    std::deque<std::pair<std::uint64_t, double>> external;
    {
      std::lock_guard<std::mutex> lock(mu_);
      external.swap(submitted_);
    }
    for (const auto& [id, t] : external) submit(id, t);

    // Sleep until the child writes, someone submits, or the next due time.
    double wake_at = now + 0.1;
    if (o.request_period_s > 0.0 && (o.max_requests == 0 || scheduled < o.max_requests)) {
      wake_at = std::min(wake_at, t0_ + static_cast<double>(scheduled) * o.request_period_s);
    }
    if (!child) wake_at = std::min(wake_at, restart_at);
    const int timeout_ms =
        std::max(0, static_cast<int>(std::ceil((wake_at - MonotonicSeconds()) * 1000.0)));
    pollfd fds[2] = {{wake_fd_, POLLIN, 0}, {child ? child->stdout_fd() : -1, POLLIN, 0}};
    (void)poll(fds, child ? 2 : 1, timeout_ms);
    if (fds[0].revents & POLLIN) {
      std::uint64_t n = 0;
      (void)!read(wake_fd_, &n, sizeof n);
    }
    if (child && (fds[1].revents & (POLLIN | POLLHUP | POLLERR))) {
      if (!drain(0)) reap(/*stopping=*/false);
    }
  }

  if (child) {
    (void)child->SendLine("stop");
    child->RequestStop();
    const double deadline = MonotonicSeconds() + 10.0;
    while (MonotonicSeconds() < deadline && drain(100)) {
    }
    reap(/*stopping=*/true);
  }
}

}  // namespace zm
