// The device's zram swap (issue 27 §2): the swap header, /proc/swaps, and the zram manager's
// paths through a fake sysfs root (hot-add refused, swapon refused, a stale device of a killed
// run: nothing left behind); then, as root where /sys/class/zram-control exists, a real zram
// swap made and removed, a stale one of a SIGKILLed process removed by the next run, and a
// device cgroup whose anonymous memory goes to swap instead of an OOM kill.
#include "harness/swap_device.h"

#include <doctest/doctest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "harness/cgroup.h"
#include "harness/process_sample.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;

namespace fs = std::filesystem;

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
void Put(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path) << text;
}

// A fake machine under a temporary directory: sysfs with zram-control and one device `id`, /dev,
// /proc/swaps, the owner records. swapon/swapoff edit the fake /proc/swaps.
struct FakeMachine {
  std::string root;
  SwapSystem sys;
  std::vector<std::string> swapped_off;
  int swap_on_error = 0;

  explicit FakeMachine(int id) {
    root = (fs::temp_directory_path() / ("zm-swap-fake-" + std::to_string(getpid()))).string();
    fs::remove_all(root);
    sys.sysfs_root = root + "/sys";
    sys.dev_root = root + "/dev";
    sys.owner_dir = root + "/run/zonemap";
    sys.proc_swaps = root + "/proc/swaps";
    Put(sys.proc_swaps, "Filename\tType\tSize\tUsed\tPriority\n");
    Put(sys.sysfs_root + "/class/zram-control/hot_add", std::to_string(id) + "\n");
    Put(sys.sysfs_root + "/class/zram-control/hot_remove", "");
    AddDevice(id);
    fs::create_directories(sys.dev_root);
    sys.swap_on = [this](const std::string& path, int priority) {
      if (swap_on_error != 0) return swap_on_error;
      std::ofstream(sys.proc_swaps, std::ios::app)
          << path << "\tpartition\t65536\t0\t" << priority << "\n";
      return 0;
    };
    sys.swap_off = [this](const std::string& path) {
      swapped_off.push_back(path);
      Put(sys.proc_swaps, "Filename\tType\tSize\tUsed\tPriority\n");
      return 0;
    };
  }
  ~FakeMachine() { fs::remove_all(root); }
  void AddDevice(int id) {
    const std::string b = sys.sysfs_root + "/block/zram" + std::to_string(id);
    Put(b + "/comp_algorithm", "[lzo-rle] lzo lz4 zstd\n");
    Put(b + "/disksize", "0\n");
    Put(b + "/reset", "");
    Put(b + "/mm_stat",
        "    8192     2048    12288        0    12288        0        0        0\n");
    Put(sys.dev_root + "/zram" + std::to_string(id), "");
  }
  std::string Block(int id) const { return sys.sysfs_root + "/block/zram" + std::to_string(id); }
  std::string Record(int id) const { return sys.owner_dir + "/zram-" + std::to_string(id); }
  std::string HotRemoved() const {
    return Slurp(sys.sysfs_root + "/class/zram-control/hot_remove");
  }
};

// A pid that is certainly not running: a child that has exited and been reaped.
pid_t DeadPid() {
  const pid_t pid = fork();
  if (pid == 0) _exit(0);
  int status = 0;
  waitpid(pid, &status, 0);
  return pid;
}

TEST_CASE("the swap header is mkswap's: version 1, last page, SWAPSPACE2 at the page's end") {
  auto page = SwapHeaderPage(64 * kMiB, 4096);
  REQUIRE(page.ok());
  REQUIRE(page->size() == 4096);
  CHECK(page->substr(4096 - 10) == "SWAPSPACE2");
  std::uint32_t version = 0, last = 0;
  std::memcpy(&version, page->data() + 1024, 4);
  std::memcpy(&last, page->data() + 1028, 4);
  CHECK(version == 1);
  CHECK(last == 64 * kMiB / 4096 - 1);
  // Too small a device, a page size that is not one: errors that say so.
  auto small = SwapHeaderPage(8 * 4096, 4096);
  REQUIRE_FALSE(small.ok());
  CHECK(small.status().message().find("10 to 2^32 pages") != std::string::npos);
  CHECK_FALSE(SwapHeaderPage(64 * kMiB, 3000).ok());
}

TEST_CASE("/proc/swaps: the active swaps, and whether a path is one of them") {
  const std::string text =
      "Filename\t\t\t\tType\t\tSize\t\tUsed\t\tPriority\n"
      "/dev/zram1                              partition\t3979260\t\t0\t\t5\n"
      "/swapfile                               file\t\t1048572\t\t0\t\t-2\n";
  const ActiveSwaps a = ParseProcSwaps(text);
  CHECK(a.count == 2);
  CHECK(a.first == "/dev/zram1");
  CHECK(a.total_bytes == (3979260ULL + 1048572ULL) * 1024);
  CHECK(ProcSwapsContains(text, "/dev/zram1"));
  CHECK_FALSE(ProcSwapsContains(text, "/dev/zram"));
  CHECK(ParseProcSwaps("Filename\tType\tSize\tUsed\tPriority\n").count == 0);
}

TEST_CASE(
    "a zram swap through a fake sysfs: lz4, disksize, header, swapon, Remove leaves nothing") {
  FakeMachine m(7);
  SwapOptions o{.requested = "zram", .bytes = 32 * kMiB + 100, .system = m.sys};
  DeviceSwap s = OpenDeviceSwap(o);
  REQUIRE_MESSAGE(s.kind() == SwapKind::kZram, s.reason());
  CHECK(s.bytes() == 32 * kMiB);  // whole pages
  CHECK(s.zram_id() == 7);
  CHECK(s.comp_algorithm() == "lz4");
  CHECK(Slurp(m.Block(7) + "/comp_algorithm") == "lz4");
  CHECK(Slurp(m.Block(7) + "/disksize") == std::to_string(32 * kMiB));
  const std::string header = Slurp(m.sys.dev_root + "/zram7");
  REQUIRE(header.size() >= 4096);
  CHECK(header.substr(static_cast<std::size_t>(sysconf(_SC_PAGESIZE)) - 10, 10) == "SWAPSPACE2");
  CHECK(ProcSwapsContains(Slurp(m.sys.proc_swaps), m.sys.dev_root + "/zram7"));
  // The owner record: this process, by pid and start time.
  std::istringstream rec(Slurp(m.Record(7)));
  long pid = 0;
  unsigned long long start = 0;
  rec >> pid >> start;
  CHECK(pid == getpid());
  CHECK(start == ProcessStartTicks(getpid()));
  const ZramSample z = s.Sample();
  CHECK(z.ok);
  CHECK(z.orig_data_bytes == 8192);
  CHECK(z.compr_data_bytes == 2048);
  CHECK(z.mem_used_bytes == 12288);

  REQUIRE(s.Remove().ok());
  CHECK(m.swapped_off == std::vector<std::string>{m.sys.dev_root + "/zram7"});
  CHECK(Slurp(m.Block(7) + "/reset") == "1");
  CHECK(m.HotRemoved() == "7");
  CHECK_FALSE(fs::exists(m.Record(7)));
  CHECK(s.Remove().ok());  // idempotent
}

TEST_CASE("faults: no hot_add, swapon refused: kind none, one reason, nothing left behind") {
  SUBCASE("the zram module is absent (or this is not root)") {
    FakeMachine m(3);
    fs::remove(m.sys.sysfs_root + "/class/zram-control/hot_add");
    DeviceSwap s = OpenDeviceSwap({.requested = "zram", .bytes = 32 * kMiB, .system = m.sys});
    CHECK(s.kind() == SwapKind::kNone);
    CHECK(s.bytes() == 0);
    CHECK(s.reason().find("cannot hot-add a zram device") != std::string::npos);
    CHECK(s.reason().find('\n') == std::string::npos);
    CHECK_FALSE(fs::exists(m.Record(3)));
  }
  SUBCASE("swapon refused") {
    FakeMachine m(4);
    m.swap_on_error = EPERM;
    DeviceSwap s = OpenDeviceSwap({.requested = "zram", .bytes = 32 * kMiB, .system = m.sys});
    CHECK(s.kind() == SwapKind::kNone);
    CHECK(s.reason().find("swapon " + m.sys.dev_root + "/zram4 refused") != std::string::npos);
    // The half-made device is gone: reset, hot-removed, no record.
    CHECK(Slurp(m.Block(4) + "/reset") == "1");
    CHECK(m.HotRemoved() == "4");
    CHECK_FALSE(fs::exists(m.Record(4)));
    CHECK(m.swapped_off.empty());
  }
  SUBCASE("the profile asks for none") {
    FakeMachine m(5);
    DeviceSwap s = OpenDeviceSwap({.requested = "none", .bytes = 0, .system = m.sys});
    CHECK(s.kind() == SwapKind::kNone);
    CHECK(s.reason() == "the profile's device.swap is none");
    CHECK(Slurp(m.Block(5) + "/disksize") == "0\n");  // untouched
  }
}

TEST_CASE("a swap already active (a real Jetson's own zram) is used, nothing is made") {
  FakeMachine m(6);
  Put(m.sys.proc_swaps,
      "Filename\tType\tSize\tUsed\tPriority\n/dev/zram0\tpartition\t3979260\t0\t5\n");
  DeviceSwap s = OpenDeviceSwap({.requested = "zram", .bytes = 64 * kMiB, .system = m.sys});
  CHECK(s.kind() == SwapKind::kExisting);
  CHECK(s.bytes() == 64 * kMiB);
  CHECK(s.device_path() == "/dev/zram0");
  CHECK(Slurp(m.Block(6) + "/disksize") == "0\n");
  CHECK_FALSE(s.Sample().ok);
  REQUIRE(s.Remove().ok());
  CHECK(m.swapped_off.empty());  // not ours: never switched off
}

TEST_CASE(
    "a stale zram device of a killed run is removed, a live owner's and unrecorded ones stay") {
  FakeMachine m(2);
  m.AddDevice(8);
  m.AddDevice(9);
  const pid_t dead = DeadPid();
  Put(m.Record(8), std::to_string(dead) + " 12345\n");
  Put(m.Record(9),
      std::to_string(getpid()) + " " + std::to_string(ProcessStartTicks(getpid())) + "\n");
  // zram2 has no record (JetPack's, or another tool's): never touched.
  Put(m.sys.proc_swaps, "Filename\tType\tSize\tUsed\tPriority\n" + m.sys.dev_root +
                            "/zram8\tpartition\t65536\t0\t5\n");
  auto removed = RemoveStaleZramDevices(m.sys);
  REQUIRE(removed.ok());
  CHECK(*removed == 1);
  CHECK(m.swapped_off == std::vector<std::string>{m.sys.dev_root + "/zram8"});
  CHECK(Slurp(m.Block(8) + "/reset") == "1");
  CHECK(m.HotRemoved() == "8");
  CHECK_FALSE(fs::exists(m.Record(8)));
  CHECK(fs::exists(m.Record(9)));
  CHECK(Slurp(m.Block(9) + "/reset").empty());
  CHECK(Slurp(m.Block(2) + "/reset").empty());
}

// The real machine: root with the zram module, and no swap active (which would be "existing").
bool RealZramOrSkip() {
  if (geteuid() != 0) {
    MESSAGE("SKIPPED: not root: swapon(2) and zram's hot_add need root");
    return false;
  }
  if (!fs::exists("/sys/class/zram-control/hot_add")) {
    MESSAGE("SKIPPED: no /sys/class/zram-control (the zram module is not loaded)");
    return false;
  }
  if (ParseProcSwaps(Slurp("/proc/swaps")).count != 0) {
    MESSAGE("SKIPPED: a swap is already active here; the run would use it (kind existing)");
    return false;
  }
  return true;
}

bool ZramBlockExists(int id) { return fs::exists("/sys/block/zram" + std::to_string(id)); }

TEST_CASE("a real zram swap: made, active, removed") {
  if (!RealZramOrSkip()) return;
  DeviceSwap s = OpenDeviceSwap({.requested = "zram", .bytes = 32 * kMiB, .system = {}});
  if (s.kind() != SwapKind::kZram) {
    MESSAGE("SKIPPED: no zram swap here: " << s.reason());
    return;
  }
  const int id = s.zram_id();
  CHECK(ProcSwapsContains(Slurp("/proc/swaps"), s.device_path()));
  CHECK(ZramBlockExists(id));
  CHECK(s.Sample().ok);
  REQUIRE(s.Remove().ok());
  CHECK_FALSE(ProcSwapsContains(Slurp("/proc/swaps"), "/dev/zram" + std::to_string(id)));
  CHECK_FALSE(ZramBlockExists(id));
  CHECK_FALSE(fs::exists("/run/zonemap/zram-" + std::to_string(id)));
}

TEST_CASE("a real zram swap left by a SIGKILLed run is removed by the next one") {
  if (!RealZramOrSkip()) return;
  int fds[2];
  REQUIRE(pipe(fds) == 0);
  const pid_t child = fork();
  if (child == 0) {
    close(fds[0]);
    DeviceSwap s = OpenDeviceSwap({.requested = "zram", .bytes = 16 * kMiB, .system = {}});
    const int id = s.kind() == SwapKind::kZram ? s.zram_id() : -1;
    (void)!write(fds[1], &id, sizeof id);
    pause();  // killed here, with the swap on
    _exit(0);
  }
  close(fds[1]);
  int id = -1;
  REQUIRE(read(fds[0], &id, sizeof id) == static_cast<ssize_t>(sizeof id));
  close(fds[0]);
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  if (id < 0) {
    MESSAGE("SKIPPED: the child could not make a zram swap");
    return;
  }
  CHECK(ProcSwapsContains(Slurp("/proc/swaps"), "/dev/zram" + std::to_string(id)));
  auto removed = RemoveStaleZramDevices(SwapSystem{});
  REQUIRE_MESSAGE(removed.ok(), removed.status().ToString());
  CHECK(*removed >= 1);
  CHECK_FALSE(ProcSwapsContains(Slurp("/proc/swaps"), "/dev/zram" + std::to_string(id)));
  CHECK_FALSE(ZramBlockExists(id));
}

TEST_CASE("a device cgroup with zram: anonymous memory beyond the limit goes to swap, not OOM") {
  if (!RealZramOrSkip()) return;
  DeviceSwap swap = OpenDeviceSwap({.requested = "zram", .bytes = 64 * kMiB, .system = {}});
  if (swap.kind() != SwapKind::kZram) {
    MESSAGE("SKIPPED: no zram swap here: " << swap.reason());
    return;
  }
  CgroupOptions co;
  co.prefix = "zm-test";
  co.limit_bytes = 32 * kMiB;
  co.swap_bytes = swap.bytes();
  co.swappiness = 60;
  auto cg = Cgroup::Create(co);
  if (!cg.ok()) {
    MESSAGE("SKIPPED: no memory cgroup can be created here: " << cg.status().message());
    return;
  }
  CHECK(cg->swap_limit_bytes() == 64 * kMiB);
  if (cg->version() == CgroupVersion::kV1) {
    CHECK(Slurp(cg->dir() + "/memory.memsw.limit_in_bytes") ==
          std::to_string(32 * kMiB + 64 * kMiB) + "\n");
    CHECK(Slurp(cg->dir() + "/memory.swappiness") == "60\n");
  } else {
    CHECK(Slurp(cg->dir() + "/memory.swap.max") == std::to_string(64 * kMiB) + "\n");
  }
  int fds[2];
  REQUIRE(pipe(fds) == 0);
  const pid_t child = fork();
  if (child == 0) {
    close(fds[0]);
    if (cg->EnterSelf() != 0) _exit(3);
    // 56 MiB of pseudo-random (so barely compressible) anonymous pages: 24 MiB over the limit.
    const std::size_t bytes = 56 * kMiB;
    auto* p = static_cast<std::uint64_t*>(
        mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
    if (p == MAP_FAILED) _exit(4);
    std::uint64_t x = 88172645463325252ULL;
    for (std::size_t i = 0; i < bytes / 8; ++i) {
      x ^= x << 13;
      x ^= x >> 7;
      x ^= x << 17;
      p[i] = x;
    }
    (void)!write(fds[1], "x", 1);
    pause();
    _exit(0);
  }
  close(fds[1]);
  char c = 0;
  const bool filled = read(fds[0], &c, 1) == 1;
  close(fds[0]);
  const CgroupSample sample = cg->Sample();
  ProcessSampler ps;
  if (auto o = ProcessSampler::Open(child); o.ok()) ps = std::move(o).value();
  const ProcessSample me = ps.Sample();
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  CHECK(filled);  // not OOM-killed: the excess went to swap
  CHECK(sample.oom_kills == 0);
  CHECK(sample.swap_bytes >= 16 * kMiB);
  CHECK(me.swap_bytes >= 16 * kMiB);
  CHECK(swap.Sample().mem_used_bytes > 0);
  REQUIRE(cg->Remove().ok());
  REQUIRE(swap.Remove().ok());
}

}  // namespace
}  // namespace zm
