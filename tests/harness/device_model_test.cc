// The device the experiment opens: a cgroup where one can be made, else the ledger with the
// reason and "simulated" in its description; --device parsing; children spawned or forked into
// the device before they run; errors that name what failed.
#include "harness/device_model.h"

#include <doctest/doctest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>

#include "support/counting_allocator.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;
using test::Reap;

std::string TestLedgerPath() {
  return std::filesystem::temp_directory_path().string() + "/zm-device-model-test-" +
         std::to_string(getpid());
}

// The cgroup device, or nullptr after saying why none can be made here.
std::unique_ptr<DeviceModel> CgroupDeviceOrSkip(std::uint64_t limit) {
  DeviceModelOptions o;
  o.limit_bytes = limit;
  o.fall_back_to_ledger = false;
  o.cgroup.prefix = "zm-test";
  auto d = OpenDeviceModel(o);
  if (!d.ok()) {
    MESSAGE("SKIPPED: no memory cgroup can be created here: " << d.status().message());
    return nullptr;
  }
  return std::move(d).value();
}

TEST_CASE("--device takes cgroup or ledger") {
  CHECK(ParseDeviceKind("cgroup").value() == DeviceKind::kCgroup);
  CHECK(ParseDeviceKind("ledger").value() == DeviceKind::kLedger);
  auto bad = ParseDeviceKind("ram");
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("'ram'") != std::string::npos);
  CHECK(DeviceKindName(DeviceKind::kCgroup) == "cgroup");
  CHECK(DeviceKindName(DeviceKind::kLedger) == "ledger");
}

TEST_CASE("no cgroup: the ledger stands in, says it is simulated and why") {
  DeviceModelOptions o;
  o.limit_bytes = 64 * kMiB;
  o.cgroup.parent_dir = "/nonexistent/zm-parent";  // a cgroup that cannot be made anywhere
  o.ledger_path = TestLedgerPath();
  auto d = OpenDeviceModel(o);
  REQUIRE_MESSAGE(d.ok(), d.status().ToString());
  DeviceModel& dev = **d;
  CHECK(dev.kind() == DeviceKind::kLedger);
  CHECK(dev.simulated());
  CHECK(dev.limit_bytes() == 64 * kMiB);
  CHECK(dev.fallback_reason().find("/nonexistent/zm-parent") != std::string::npos);
  CHECK(dev.Describe().find("simulated") != std::string::npos);
  CHECK(dev.Describe().find("/nonexistent/zm-parent") != std::string::npos);
  REQUIRE(dev.ledger() != nullptr);
  CHECK(dev.cgroup() == nullptr);
  CHECK(dev.EnterSelf() == 0);

  // Tenants register with the ledger; the device's sample is the ledger's.
  auto t = dev.ledger()->Register("map", 40 * kMiB);
  REQUIRE(t.ok());
  CHECK_FALSE(t->TryUpdate(80 * kMiB));  // refused: a simulated out-of-memory event
  const DeviceSample s = dev.Sample();
  CHECK(s.ok);
  CHECK(s.usage_bytes == 40 * kMiB);
  CHECK(s.peak_bytes == 40 * kMiB);
  CHECK(s.oom_kills == 1);
  CHECK(s.under_oom);
  t->Release();
  CHECK(dev.Remove().ok());
  CHECK_FALSE(std::filesystem::exists(o.ledger_path));
}

TEST_CASE("asked for a cgroup explicitly, a machine without one is an error, not a fallback") {
  DeviceModelOptions o;
  o.limit_bytes = 64 * kMiB;
  o.fall_back_to_ledger = false;
  o.cgroup.parent_dir = "/nonexistent/zm-parent";
  auto d = OpenDeviceModel(o);
  REQUIRE_FALSE(d.ok());
  CHECK(d.status().message().find("/nonexistent/zm-parent") != std::string::npos);
  o.limit_bytes = 0;
  CHECK(OpenDeviceModel(o).status().message().find("limit_bytes is 0") != std::string::npos);
}

TEST_CASE("the ledger on request, without trying a cgroup") {
  DeviceModelOptions o;
  o.kind = DeviceKind::kLedger;
  o.limit_bytes = 32 * kMiB;
  o.ledger_path = TestLedgerPath();
  auto d = OpenDeviceModel(o);
  REQUIRE(d.ok());
  CHECK((*d)->simulated());
  CHECK((*d)->fallback_reason().empty());
  CHECK((*d)->Remove().ok());
}

TEST_CASE("a cgroup device: a spawned program is inside before it runs") {
  auto dev = CgroupDeviceOrSkip(64 * kMiB);
  if (!dev) return;
  CHECK(dev->kind() == DeviceKind::kCgroup);
  CHECK_FALSE(dev->simulated());
  CHECK(dev->limit_bytes() == 64 * kMiB);
  Cgroup* cg = dev->cgroup();
  REQUIRE(cg != nullptr);
  const std::string dir = cg->dir();
  CHECK(dev->Describe().find(dir) != std::string::npos);
  MESSAGE(dev->Describe());

  // A program that prints the cgroup it runs in: inside from its first instruction.
  std::array<int, 2> out{};
  REQUIRE(pipe(out.data()) == 0);
  SpawnRequest req;
  req.argv = {"cat", "/proc/self/cgroup"};
  req.stdout_fd = out[1];
  auto pid = SpawnInDevice(req, *dev);
  close(out[1]);
  if (!pid.ok()) {
    close(out[0]);
    // qemu-user cannot exec a host program from an emulated one without binfmt_misc.
    MESSAGE("SKIPPED: cannot spawn here: " << pid.status().message());
    return;
  }
  std::string text;
  std::array<char, 512> buf{};
  for (ssize_t n; (n = read(out[0], buf.data(), buf.size())) > 0;)
    text.append(buf.data(), static_cast<std::size_t>(n));
  close(out[0]);
  const int status = Reap(*pid);
  CHECK(WIFEXITED(status));
  const std::string leaf = std::filesystem::path(dir).filename().string();
  CAPTURE(text);
  CHECK(text.find(leaf) != std::string::npos);
  CHECK(dev->Remove().ok());
}

TEST_CASE("spawning a program that does not exist names it, and nothing is left running") {
  DeviceModelOptions o;
  o.kind = DeviceKind::kLedger;
  o.limit_bytes = 32 * kMiB;
  o.ledger_path = TestLedgerPath();
  auto d = OpenDeviceModel(o);
  REQUIRE(d.ok());
  SpawnRequest req;
  req.argv = {"/nonexistent/zm-program", "--x"};
  auto pid = SpawnInDevice(req, **d);
  REQUIRE_FALSE(pid.ok());
  CHECK(pid.status().message().find("/nonexistent/zm-program") != std::string::npos);
  CHECK(SpawnInDevice(SpawnRequest{}, **d).status().message().find("empty") != std::string::npos);
  CHECK((*d)->Remove().ok());
}

// A device no child can enter (EnterSelf fails as a cgroup's procs file would for EACCES).
class RefusingDevice final : public DeviceModel {
 public:
  DeviceKind kind() const noexcept override { return DeviceKind::kCgroup; }
  std::uint64_t limit_bytes() const noexcept override { return 32 * kMiB; }
  std::string Describe() const override { return "refusing test device"; }
  Status AddProcess(pid_t) override { return Status::Ok(); }
  int EnterSelf() const noexcept override { return EACCES; }
  DeviceSample Sample() noexcept override { return {}; }
  Status Remove() override { return Status::Ok(); }
};

// True when the calling process has no child left, running or unreaped.
bool NoChildLeft() {
  int status = 0;
  return waitpid(-1, &status, WNOHANG) < 0 && errno == ECHILD;
}

TEST_CASE("a child that cannot enter the device never runs, spawn and fork name the device") {
  const RefusingDevice dev;
  std::array<int, 2> out{};
  REQUIRE(pipe(out.data()) == 0);
  SpawnRequest req;
  req.argv = {"echo", "ran outside the device"};
  req.stdout_fd = out[1];
  auto spawned = SpawnInDevice(req, dev);
  close(out[1]);
  REQUIRE_FALSE(spawned.ok());
  CHECK(spawned.status().message().find("spawn echo") != std::string::npos);
  CHECK(spawned.status().message().find("could not enter the device (refusing test device)") !=
        std::string::npos);
  std::array<char, 64> buf{};
  CHECK(read(out[0], buf.data(), buf.size()) == 0);  // it never ran: nothing written
  close(out[0]);

  auto forked = ForkInDevice(dev);  // the child exits 127 in there: only the parent goes on
  REQUIRE_FALSE(forked.ok());
  CHECK(forked.status().message().find("could not enter the device (refusing test device)") !=
        std::string::npos);
  CHECK(NoChildLeft());
}

TEST_CASE("a spawned program reads the stdin it was given and writes the stdout") {
  DeviceModelOptions o;
  o.kind = DeviceKind::kLedger;
  o.limit_bytes = 32 * kMiB;
  o.ledger_path = TestLedgerPath();
  auto d = OpenDeviceModel(o);
  REQUIRE(d.ok());
  // Close-on-exec, so the child keeps only its stdin and stdout (and sees the end of its input).
  std::array<int, 2> in{};
  std::array<int, 2> out{};
  REQUIRE(pipe2(in.data(), O_CLOEXEC) == 0);
  REQUIRE(pipe2(out.data(), O_CLOEXEC) == 0);
  SpawnRequest req;
  req.argv = {"cat"};
  req.stdin_fd = in[0];
  req.stdout_fd = out[1];
  auto pid = SpawnInDevice(req, **d);
  close(in[0]);
  close(out[1]);
  if (!pid.ok()) {
    close(in[1]);
    close(out[0]);
    MESSAGE("SKIPPED: cannot spawn here: " << pid.status().message());
    CHECK((*d)->Remove().ok());
    return;
  }
  REQUIRE(write(in[1], "zones\n", 6) == 6);
  close(in[1]);
  std::string text;
  std::array<char, 64> buf{};
  for (ssize_t n; (n = read(out[0], buf.data(), buf.size())) > 0;)
    text.append(buf.data(), static_cast<std::size_t>(n));
  close(out[0]);
  const ChildExit e = DescribeWaitStatus(Reap(*pid));
  CHECK(e.exited);
  CHECK(e.code == 0);
  CHECK(text == "zones\n");
  CHECK((*d)->Remove().ok());
}

TEST_CASE("a forked child is inside the cgroup device and the device's sample is allocation-free") {
  auto dev = CgroupDeviceOrSkip(64 * kMiB);
  if (!dev) return;
  std::array<int, 2> up{};
  REQUIRE(pipe(up.data()) == 0);
  auto pid = ForkInDevice(*dev);
  REQUIRE_MESSAGE(pid.ok(), pid.status().ToString());
  if (*pid == 0) {
    (void)!write(up[1], "r", 1);
    for (;;) pause();
  }
  char c = 0;
  REQUIRE(read(up[0], &c, 1) == 1);
  close(up[0]);
  close(up[1]);
  Cgroup* cg = dev->cgroup();
  REQUIRE(cg != nullptr);
  auto procs = cg->Processes();
  REQUIRE(procs.ok());
  CHECK(std::find(procs->begin(), procs->end(), *pid) != procs->end());
  CHECK(std::find(procs->begin(), procs->end(), getpid()) == procs->end());

  test::AllocationCounter counter;
  std::uint64_t usage = 0;
  for (int i = 0; i < 1000; ++i) usage += dev->Sample().usage_bytes;
  CHECK(counter.allocations() == 0);
  CHECK(usage > 0);

  CHECK(dev->Remove().ok());  // kills the child
  const ChildExit e = DescribeWaitStatus(Reap(*pid));
  CHECK(e.signaled);
  CHECK(e.signal == SIGKILL);
}

}  // namespace
}  // namespace zm
