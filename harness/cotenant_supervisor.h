// The co-tenant as a service, for the experiment: spawn zonemap-cotenant (optionally placed in
// the device's memory cgroup before it maps anything), feed it requests on a schedule that is
// the same for every run, watch it, and when it dies restart it after a delay as a service manager
// would (Ollama's systemd unit: Restart=always, RestartSec=3), counting the restarts. Every event
// line of every instance is folded into one CotenantResult (and optionally appended to a JSONL
// file as it arrives), so what happened before a kill is never lost.
//
// Requests: the child reads commands on stdin ("start", "request ID SUBMITTED", "stop"). A request
// due while no child is running fails ("the co-tenant was not running"); requests queued or in
// flight in a child that dies fail ("lost"); those still open at Stop() are "unfinished".
//
// Deaths: by SIGKILL = killed (an OOM kill in the cgroup experiment), by another signal =
// crashed; an exit after "failed_to_start" is a failed start. The child is restarted in each case.
//
// Invariants: one supervisor thread owns the child; SubmitRequest/Snapshot are thread-safe;
// Stop() (or the destructor) ends the child (SIGTERM, then SIGKILL after a grace period) and
// joins the thread; the process running the supervisor never enters the cgroup.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "common/status.h"
#include "harness/cotenant.h"

namespace zm {

struct CotenantSupervisorOptions {
  CotenantConfig config;   // what every instance runs (config.requests is not used)
  std::string executable;  // empty = FindCotenantExecutable()
  // Puts each new child in the device. Preferred: device (outliving the supervisor's run),
  // entered by the child between fork and exec (SpawnInDevice, harness/device_model.h), so not
  // one page of it is charged outside. Or place_child, called with the pid once it is running
  // but before it maps anything (it waits for "start"), e.g. PlaceInCgroupProcs(
  // ".../cgroup.procs") or DeviceModel::AddProcess: what the program's start-up touched stays
  // charged where it was. Either failing is a failed start.
  const DeviceModel* device = nullptr;
  std::function<Status(pid_t)> place_child;
  double restart_delay_s = 3.0;    // [cotenant] restart_delay_s
  std::uint32_t max_restarts = 0;  // 0 = unlimited (Restart=always)
  // Pacing, set identically for every run of an experiment: request i is submitted at
  // Start() + i * request_period_s on the wall clock, at most max_requests of them (0 = until
  // Stop()). Period 0: requests come only from SubmitRequest() (e.g. on the frames' clock).
  double request_period_s = 0.0;
  std::uint32_t max_requests = 0;
  std::string events_path;  // every event line appended and flushed as it arrives; empty = none
};

// A place_child hook writing the pid into a cgroup's procs file (v1 "cgroup.procs" or "tasks",
// v2 "cgroup.procs"); the cgroup itself is the device module's.
[[nodiscard]] std::function<Status(pid_t)> PlaceInCgroupProcs(std::string procs_path);

class CotenantSupervisor {
 public:
  CotenantSupervisor() = default;
  CotenantSupervisor(const CotenantSupervisor&) = delete;
  CotenantSupervisor& operator=(const CotenantSupervisor&) = delete;
  ~CotenantSupervisor();  // Stop() if still running

  // Creates the weights file if it is absent (here, outside the device), then starts the
  // supervisor thread; the first child is spawned at once. kFailedPrecondition if already
  // started; kInvalidArgument for a configuration the co-tenant would refuse.
  [[nodiscard]] Status Start(CotenantSupervisorOptions options);
  // Submits one request now (thread-safe); returns its id.
  std::uint64_t SubmitRequest();
  // The report so far (thread-safe; quantiles and outcome as of now).
  [[nodiscard]] CotenantResult Snapshot() const;
  // Stops the child cleanly, joins, and returns the final report.
  [[nodiscard]] Result<CotenantResult> Stop();

  // The running child's pid, -1 between instances (tests kill it to play the OOM killer).
  [[nodiscard]] pid_t child_pid() const noexcept { return child_pid_.load(); }
  [[nodiscard]] std::uint32_t instances() const noexcept { return instances_.load(); }

 private:
  void Loop();
  void Record(nlohmann::json event);   // the supervisor's own events, stamped
  void Line(const std::string& line);  // a child's line
  void Wake();

  CotenantSupervisorOptions options_;
  double t0_ = 0.0;
  std::thread thread_;
  std::atomic<bool> quit_{false};
  std::atomic<pid_t> child_pid_{-1};
  std::atomic<std::uint32_t> instances_{0};
  std::atomic<std::uint64_t> next_id_{0};
  int wake_fd_ = -1;
  std::FILE* events_ = nullptr;
  mutable std::mutex mu_;  // guards builder_ and submitted_
  CotenantReportBuilder builder_;
  std::deque<std::pair<std::uint64_t, double>> submitted_;  // external requests not yet sent
};

}  // namespace zm
