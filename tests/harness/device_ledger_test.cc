// Device ledger: two handles (and a forked process) on one file see the same totals; a grant
// that would exceed the device is refused and counted as an out-of-memory event; the device is
// over-committed until the refused demand goes away; dead processes' slots can be reaped.
#include "harness/device_ledger.h"

#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/counting_allocator.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;

// A fresh ledger path per test, removed at the end.
struct TempLedger {
  std::string path;
  TempLedger() {
    static std::atomic<int> n{0};
    path = (std::filesystem::temp_directory_path() /
            ("zm-ledger-test-" + std::to_string(getpid()) + "-" + std::to_string(n++)))
               .string();
    (void)DeviceLedger::Remove(path);
  }
  ~TempLedger() { (void)DeviceLedger::Remove(path); }
};

TEST_CASE("two handles on one file share grants, refusals and the peak") {
  TempLedger tmp;
  Result<DeviceLedger> a = DeviceLedger::Open(tmp.path, 100 * kMiB);
  REQUIRE_MESSAGE(a.ok(), a.status().ToString());
  Result<DeviceLedger> b = DeviceLedger::Open(tmp.path, 0);  // attach
  REQUIRE(b.ok());
  CHECK(b->device_bytes() == 100 * kMiB);

  Result<LedgerTenant> os = a->Register("os-reserve", 20 * kMiB);
  REQUIRE(os.ok());
  Result<LedgerTenant> map = b->Register("map", 30 * kMiB);
  REQUIRE(map.ok());
  CHECK(a->sum_bytes() == 50 * kMiB);
  CHECK(b->free_bytes() == 50 * kMiB);

  // The co-tenant does not fit: refused, counted in both views, nothing granted.
  Result<LedgerTenant> big = a->Register("cotenant", 60 * kMiB);
  REQUIRE_FALSE(big.ok());
  CHECK(big.status().code() == StatusCode::kResourceExhausted);
  CHECK(b->oom_events() == 1);
  CHECK(a->sum_bytes() == 50 * kMiB);

  Result<LedgerTenant> small = a->Register("cotenant", 40 * kMiB);
  REQUIRE(small.ok());
  CHECK(b->sum_bytes() == 90 * kMiB);
  CHECK(b->peak_sum_bytes() == 90 * kMiB);

  // The map grows past the device: refused, its grant is unchanged.
  Status grow = map->Update(45 * kMiB);
  CHECK(grow.code() == StatusCode::kResourceExhausted);
  CHECK(map->bytes() == 30 * kMiB);
  CHECK(map->oom_events() == 1);
  CHECK(a->oom_events() == 2);
  CHECK(a->OverCommitted());  // its demand is still pending

  // Shrinking always succeeds and clears the pending demand.
  CHECK(map->Update(10 * kMiB).ok());
  CHECK_FALSE(a->OverCommitted());
  CHECK(b->sum_bytes() == 70 * kMiB);
  CHECK(b->peak_sum_bytes() == 90 * kMiB);

  small->Release();
  small->Release();  // idempotent
  CHECK(a->sum_bytes() == 30 * kMiB);
  const LedgerSnapshot snap = b->Snapshot();
  CHECK(snap.tenants.size() == 2);
  CHECK(snap.oom_events == 2);
  CHECK(snap.sum_bytes == 30 * kMiB);
}

TEST_CASE("a tenant releases its grant when destroyed") {
  TempLedger tmp;
  Result<DeviceLedger> ledger = DeviceLedger::Open(tmp.path, 10 * kMiB);
  REQUIRE(ledger.ok());
  {
    Result<LedgerTenant> t = ledger->Register("scoped", 4 * kMiB);
    REQUIRE(t.ok());
    CHECK(ledger->sum_bytes() == 4 * kMiB);
  }
  CHECK(ledger->sum_bytes() == 0);
}

TEST_CASE("Update and OverCommitted never allocate") {
  TempLedger tmp;
  Result<DeviceLedger> ledger = DeviceLedger::Open(tmp.path, 10 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> t = ledger->Register("map", 0);
  REQUIRE(t.ok());
  test::AllocationCounter counter;
  int granted = 0;
  for (std::uint64_t i = 0; i < 1000; ++i) {
    granted += t->TryUpdate((i % 20) * kMiB) ? 1 : 0;  // half of these exceed the device
    (void)ledger->OverCommitted();
  }
  CHECK(counter.allocations() == 0);
  CHECK(granted == 550);
  CHECK(ledger->oom_events() == 450);
}

TEST_CASE("a forked process registers in the same ledger, its slot is reaped after it dies") {
  TempLedger tmp;
  Result<DeviceLedger> ledger = DeviceLedger::Open(tmp.path, 64 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> map = ledger->Register("map", 16 * kMiB);
  REQUIRE(map.ok());
  int to_child[2];
  REQUIRE(pipe(to_child) == 0);
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    // Child: its own handle on the file; grows until refused; exits without releasing.
    close(to_child[1]);
    int code = 0;
    Result<DeviceLedger> mine = DeviceLedger::Open(tmp.path, 0);
    if (!mine.ok()) _exit(10);
    Result<LedgerTenant> co = mine->Register("cotenant", 32 * kMiB);
    if (!co.ok()) _exit(11);
    if (co->TryUpdate(64 * kMiB)) code = 12;  // 16 + 64 > 64: must be refused
    char c = 0;
    if (read(to_child[0], &c, 1) != 1) code = 13;  // wait until the parent has looked
    _exit(code);  // no destructors run: the slot stays taken, as after a crash
  }
  close(to_child[0]);
  // Parent: sees the child's grant and its refused growth.
  for (int i = 0; i < 5000 && ledger->sum_bytes() != 48 * kMiB; ++i) usleep(1000);
  CHECK(ledger->sum_bytes() == 48 * kMiB);
  for (int i = 0; i < 5000 && ledger->oom_events() == 0; ++i) usleep(1000);
  CHECK(ledger->oom_events() == 1);
  CHECK(ledger->OverCommitted());
  REQUIRE(write(to_child[1], "x", 1) == 1);
  close(to_child[1]);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  CHECK(ledger->sum_bytes() == 48 * kMiB);  // the dead child still holds its grant
  CHECK(ledger->ReapDeadTenants() == 1);
  CHECK(ledger->sum_bytes() == 16 * kMiB);
  CHECK_FALSE(ledger->OverCommitted());
}

TEST_CASE("bad files, mismatched totals, long names and full tables are errors") {
  TempLedger tmp;
  CHECK(DeviceLedger::Open(tmp.path, 0).status().code() == StatusCode::kInvalidArgument);
  (void)DeviceLedger::Remove(tmp.path);
  Result<DeviceLedger> ledger = DeviceLedger::Open(tmp.path, 10 * kMiB);
  REQUIRE(ledger.ok());
  CHECK(DeviceLedger::Open(tmp.path, 20 * kMiB).status().code() == StatusCode::kInvalidArgument);
  CHECK_FALSE(ledger->Register(std::string(kLedgerNameBytes, 'x'), 0).ok());
  CHECK_FALSE(ledger->Register("", 0).ok());
  std::vector<LedgerTenant> held;
  for (std::uint32_t i = 0; i < kLedgerMaxTenants; ++i) {
    char name[16];
    std::snprintf(name, sizeof name, "t%u", i);  // not "t" + to_string: GCC 12 -O3 -Wrestrict
    Result<LedgerTenant> t = ledger->Register(name, 0);
    REQUIRE(t.ok());
    held.push_back(std::move(t).value());
  }
  CHECK(ledger->Register("one-too-many", 0).status().code() == StatusCode::kOutOfRange);

  TempLedger junk;
  std::ofstream(junk.path) << "not a ledger";
  CHECK(DeviceLedger::Open(junk.path, 0).status().code() == StatusCode::kCorrupt);
}

}  // namespace
}  // namespace zm
