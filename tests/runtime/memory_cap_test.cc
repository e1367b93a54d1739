// Memory caps: in a forked child, a setrlimit cap makes a large allocation fail; the failure is
// caught at the boundary helper and counted, and the child carries on. Where the cap cannot be
// enforced (qemu-user ignores RLIMIT_AS/RLIMIT_DATA) the report must say so.
#include "runtime/memory_cap.h"

#include <doctest/doctest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <new>
#include <string>

#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;

TEST_CASE("GuardAllocation turns std::bad_alloc into a counted ResourceExhausted") {
  const std::uint64_t before = AllocFailureCount();
  Status ok = GuardAllocation("nothing", [] {});
  CHECK(ok.ok());
  Status failed = GuardAllocation("a keyframe batch", [] { throw std::bad_alloc(); });
  CHECK(failed.code() == StatusCode::kResourceExhausted);
  CHECK(failed.message().find("a keyframe batch") != std::string::npos);
  CHECK(AllocFailureCount() == before + 1);
}

TEST_CASE("a mapping the kernel refuses is counted, not fatal") {
  const std::uint64_t before = AllocFailureCount();
  CHECK(TryMapBytes(std::size_t{1} << 62) == nullptr);  // beyond any address space
  CHECK(AllocFailureCount() == before + 1);
  void* p = TryMapBytes(kMiB);
  REQUIRE(p != nullptr);
  std::memset(p, 1, kMiB);
  UnmapBytes(p, kMiB);
  CHECK(TryMalloc(0) == nullptr);
  CHECK(AllocFailureCount() == before + 1);
}

TEST_CASE("no cap requested: nothing is applied") {
  Result<CapReport> r = ApplyProcessCap(0);
  REQUIRE(r.ok());
  CHECK(r->resource == CapResource::kNone);
  CHECK_FALSE(r->enforced);
}

TEST_CASE("a cap below what the process already maps is refused") {
  if (BuiltWithAddressSanitizer()) {
    // Only growth is capped under ASan, so no cap is "below" usage; RLIMIT_AS is refused.
    CHECK(ApplyProcessCap(64 * kMiB, CapMode::kAddressSpace).status().code() ==
          StatusCode::kFailedPrecondition);
    return;
  }
  CHECK(ApplyProcessCap(4096, CapMode::kAddressSpace).status().code() ==
        StatusCode::kFailedPrecondition);
}

// What the capped child saw.
struct ChildReport {
  int applied = 0;
  int enforced = 0;
  int resource = 0;
  int big_map_failed = 0;
  int small_map_ok = 0;
  int new_failed = 0;
  std::uint64_t failures_counted = 0;
  char note[256] = {};
};

// Where the capped child's large allocation escapes to (below).
char* volatile escaped_allocation = nullptr;

TEST_CASE("in a forked child, a process cap makes a large allocation fail and be counted") {
  int fds[2];
  REQUIRE(pipe(fds) == 0);
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    close(fds[0]);
    ChildReport rep;
    const std::uint64_t before = AllocFailureCount();
    // Room for 64 MiB more than the process maps now.
    const std::uint64_t cap =
        BuiltWithAddressSanitizer() ? 64 * kMiB : ProcessAddressSpaceBytes() + 64 * kMiB;
    Result<CapReport> r = ApplyProcessCap(cap);
    if (r.ok()) {
      rep.applied = 1;
      rep.enforced = r->enforced ? 1 : 0;
      rep.resource = static_cast<int>(r->resource);
      std::strncpy(rep.note, r->note.c_str(), sizeof rep.note - 1);
      void* big = TryMapBytes(256 * kMiB);
      rep.big_map_failed = big == nullptr ? 1 : 0;
      UnmapBytes(big, 256 * kMiB);
      void* small = TryMapBytes(4 * kMiB);  // the process carries on
      rep.small_map_ok = small != nullptr ? 1 : 0;
      if (small != nullptr) std::memset(small, 7, 4 * kMiB);
      UnmapBytes(small, 4 * kMiB);
      if (!BuiltWithAddressSanitizer()) {
        // Under ASan its allocator aborts on OOM instead of throwing; operator new is only
        // exercised in plain builds.
        Status s = GuardAllocation("256 MiB vector", [] {
          // Escapes through a volatile pointer: an optimised build may elide a new/delete pair
          // whose pointer nobody sees, and then nothing is allocated to fail.
          auto* p = new char[256 * kMiB];
          escaped_allocation = p;
          std::memset(p, 1, 256 * kMiB);
          delete[] p;
        });
        rep.new_failed = s.ok() ? 0 : 1;
      }
    } else {
      std::strncpy(rep.note, r.status().message().c_str(), sizeof rep.note - 1);
    }
    rep.failures_counted = AllocFailureCount() - before;
    if (write(fds[1], &rep, sizeof rep) != static_cast<ssize_t>(sizeof rep)) _exit(2);
    _exit(0);
  }
  close(fds[1]);
  ChildReport rep;
  const ssize_t n = read(fds[0], &rep, sizeof rep);
  close(fds[0]);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  REQUIRE_MESSAGE(WIFEXITED(status), "the capped child crashed");
  CHECK(WEXITSTATUS(status) == 0);
  REQUIRE(n == static_cast<ssize_t>(sizeof rep));
  INFO("child note: " << rep.note);
  REQUIRE(rep.applied == 1);
  CHECK(rep.resource == static_cast<int>(BuiltWithAddressSanitizer() ? CapResource::kData
                                                                     : CapResource::kAddressSpace));
  if (rep.enforced == 0) {
    // e.g. qemu-user: accepted but not enforced, and the report says so.
    CHECK(std::string(rep.note).find("NOT enforced") != std::string::npos);
    MESSAGE("process cap not enforced here: " << rep.note);
    return;
  }
  CHECK(rep.big_map_failed == 1);
  CHECK(rep.small_map_ok == 1);
  if (BuiltWithAddressSanitizer()) {
    CHECK(rep.failures_counted == 1);
  } else {
    CHECK(rep.new_failed == 1);
    CHECK(rep.failures_counted == 2);
  }
}

}  // namespace
}  // namespace zm
