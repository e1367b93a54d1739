// Per-process telemetry: /proc/<pid>/stat parsing (odd command names), a child's resident
// memory and faults as it touches memory, a dead process reported as gone, getrusage, and no
// allocation once the sampler is open (it runs every tick).
#include "harness/process_sample.h"

#include <doctest/doctest.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstring>

#include "support/counting_allocator.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;

TEST_CASE("stat lines: fields counted from the last parenthesis") {
  // pid (comm) state ppid pgrp session tty tpgid flags minflt cminflt majflt cmajflt utime stime
  // cutime cstime priority nice threads itrealvalue starttime vsize rss ...
  const char* line =
      "4242 (a (b) c) S 1 4242 4242 0 -1 4194560 1234 0 56 0 10 20 0 0 20 0 1 0 777 123456 89 "
      "18446744073709551615 1 1 0 0 0 0 0 0 0 0 0 0 17 0 0 0 0 0 0\n";
  ProcStat st;
  REQUIRE(ParseProcStat(line, &st));
  CHECK(st.state == 'S');
  CHECK(st.minor_faults == 1234);
  CHECK(st.major_faults == 56);
  CHECK(st.start_ticks == 777);
  CHECK(st.rss_pages == 89);
  CHECK_FALSE(ParseProcStat("", &st));
  CHECK_FALSE(ParseProcStat("12 (x) S 1 2", &st));
  CHECK_FALSE(ParseProcStat("no parenthesis here", &st));
}

TEST_CASE("a child's resident memory and faults follow what it touches and a dead child is gone") {
  std::array<int, 2> up{}, down{};
  REQUIRE(pipe(up.data()) == 0);
  REQUIRE(pipe(down.data()) == 0);
  constexpr std::size_t kBytes = 32 * kMiB;
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    char c = 0;
    void* p = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) _exit(3);
    (void)!write(up[1], "r", 1);
    (void)!read(down[0], &c, 1);
    std::memset(p, 1, kBytes);
    (void)!write(up[1], "t", 1);
    (void)!read(down[0], &c, 1);
    _exit(0);
  }
  char c = 0;
  auto sampler = ProcessSampler::Open(pid);
  REQUIRE_MESSAGE(sampler.ok(), sampler.status().ToString());
  CHECK(sampler->pid() == pid);
  REQUIRE(read(up[0], &c, 1) == 1);
  const ProcessSample before = sampler->Sample();
  REQUIRE(write(down[1], "g", 1) == 1);
  REQUIRE(read(up[0], &c, 1) == 1);
  const ProcessSample after = sampler->Sample();
  REQUIRE(write(down[1], "g", 1) == 1);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  const ProcessSample gone = sampler->Sample();
  for (int fd : {up[0], up[1], down[0], down[1]}) close(fd);

  MESSAGE("child RSS " << before.rss_bytes / 1024 << " -> " << after.rss_bytes / 1024
                       << " KiB, minor faults " << before.minor_faults << " -> "
                       << after.minor_faults);
  CHECK(before.alive);
  CHECK(after.alive);
  CHECK(after.rss_anon_bytes >= before.rss_anon_bytes + kBytes - kMiB);
  CHECK(after.rss_bytes == after.rss_anon_bytes + after.rss_file_bytes);
  // At least one fault per huge page, at most one per page.
  CHECK(after.minor_faults >= before.minor_faults + kBytes / (2 * kMiB));
  CHECK_FALSE(gone.alive);
  CHECK(gone.rss_bytes == 0);

  const RusageSample r = SampleRusage();
  CHECK(r.children_minor_faults >= kBytes / (2 * kMiB));
  CHECK(r.children_max_rss_bytes >= kBytes);
  CHECK(r.self_max_rss_bytes > 0);
}

TEST_CASE("opening a process that does not exist names it") {
  const pid_t dead = fork();
  REQUIRE(dead >= 0);
  if (dead == 0) _exit(0);
  int status = 0;
  REQUIRE(waitpid(dead, &status, 0) == dead);
  auto s = ProcessSampler::Open(dead);
  REQUIRE_FALSE(s.ok());
  CHECK(s.status().message().find(std::to_string(dead)) != std::string::npos);
}

TEST_CASE("sampling allocates nothing once open") {
  auto self = ProcessSampler::Open(getpid());
  REQUIRE(self.ok());
  test::AllocationCounter counter;
  std::uint64_t sum = 0;
  for (int i = 0; i < 1000; ++i) {
    const ProcessSample s = self->Sample();
    const RusageSample r = SampleRusage();
    sum += s.rss_bytes + r.self_minor_faults;
  }
  CHECK(counter.allocations() == 0);
  CHECK(sum > 0);
}

}  // namespace
}  // namespace zm
