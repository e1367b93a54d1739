// The co-tenant's weights file (harness/weights_file.h): created once with real bytes and reused,
// mapped read-only and shared, and evictable: pages the kernel reclaims come back as major faults
// on the next pass, which is how memory pressure costs a file-backed model tokens/s.
#include "harness/weights_file.h"

#include <doctest/doctest.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/cotenant_test_support.h"

namespace zm {
namespace {

std::string FreshDir(const char* name) {
  const std::string d = (std::filesystem::temp_directory_path() /
                         (std::string(name) + "-" + std::to_string(getpid())))
                            .string();
  std::filesystem::remove_all(d);
  return d;
}

long MajorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_majflt;
}

// Touch's sums end here, through a volatile store: callers discard them, and an optimised build
// would otherwise drop the reads Touch exists to make (no page touched, no fault counted).
volatile std::uint64_t touch_sink = 0;

std::uint64_t Touch(const MappedWeights& w) {
  std::uint64_t s = 0;
  for (std::size_t i = 0; i < w.bytes() / 8; i += 512) s += w.words()[i];  // one word per page
  touch_sink = s;
  return s;
}

TEST_CASE("the weights file is created once with real bytes, then reused") {
  const std::string dir = FreshDir("zm-weights-test");
  Result<WeightsFileInfo> a = EnsureWeightsFile(dir, 64 * kWeightsPageBytes);
  REQUIRE_MESSAGE(a.ok(), a.status().ToString());
  CHECK(a->created);
  CHECK(a->path == dir + "/" + WeightsFileName(64 * kWeightsPageBytes));
  struct stat st {};
  REQUIRE(stat(a->path.c_str(), &st) == 0);
  CHECK(st.st_size == 64 * 4096);
  CHECK(st.st_blocks * 512 >= 64 * 4096);  // written, not a sparse file
  Result<WeightsFileInfo> b = EnsureWeightsFile(dir, 64 * kWeightsPageBytes);
  REQUIRE(b.ok());
  CHECK_FALSE(b->created);
  CHECK(b->create_ms == 0.0);
  // Same size, same content: the stream depends only on the size.
  std::ifstream f(a->path, std::ios::binary);
  char head[8] = {};
  f.read(head, 8);
  CHECK(std::string(head, 8) == "ZMWEIGHT");
  std::filesystem::remove_all(dir);
}

TEST_CASE("bad sizes and unwritable directories are errors that name them") {
  Result<WeightsFileInfo> odd = EnsureWeightsFile(FreshDir("zm-weights-odd"), 1000);
  REQUIRE_FALSE(odd.ok());
  CHECK(odd.status().message().find("multiple of 4096") != std::string::npos);
  Result<WeightsFileInfo> nowhere = EnsureWeightsFile("/proc/self/zm-no", kWeightsPageBytes);
  REQUIRE_FALSE(nowhere.ok());
  CHECK(nowhere.status().message().find("/proc/self/zm-no") != std::string::npos);
  const std::string dir = FreshDir("zm-weights-bad");
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/not-weights") << std::string(4096, 'x');
  Result<MappedWeights> bad = MappedWeights::Map(dir + "/not-weights", {});
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().code() == StatusCode::kCorrupt);
  CHECK_FALSE(MappedWeights::Map(dir + "/absent", {}).ok());
  std::filesystem::remove_all(dir);
}

TEST_CASE("mmap load is file-backed, read-only and shared, read load is process memory") {
  Result<WeightsFileInfo> file = EnsureWeightsFile(test::TestWeightsDir(), 256 * kWeightsPageBytes);
  REQUIRE(file.ok());
  Result<MappedWeights> w = MappedWeights::Map(file->path, {});
  REQUIRE_MESSAGE(w.ok(), w.status().ToString());
  CHECK(w->file_backed());
  CHECK(w->bytes() == 256 * 4096);
  struct stat st {};
  REQUIRE(stat(file->path.c_str(), &st) == 0);
  CHECK(w->inode() == st.st_ino);
  WeightsMapOptions read;
  read.load = WeightsLoad::kRead;
  Result<MappedWeights> r = MappedWeights::Map(file->path, read);
  REQUIRE(r.ok());
  CHECK_FALSE(r->file_backed());
  CHECK(std::memcmp(w->data(), r->data(), w->bytes()) == 0);  // the same bytes either way
  if (test::EmulatorLauncher::active()) {
    MESSAGE("under qemu-user /proc/self/maps is the emulator's view: the mapping check is skipped");
    return;
  }
  CHECK(test::MappingPerms(test::ProcMaps(), file->path) == "r--s");
  MappedWeights moved = std::move(*w);
  CHECK(moved.bytes() == 256 * 4096);
  moved = MappedWeights();  // releases the mapping
  CHECK(test::MappingPerms(test::ProcMaps(), file->path).empty());
}

TEST_CASE("the mapped weights are evictable: reclaimed pages come back as major faults") {
  if (test::EmulatorLauncher::active()) {
    MESSAGE(
        "skipped under qemu-user: page reclaim and fault counts are the host's, not the guest's");
    return;
  }
  Result<WeightsFileInfo> file =
      EnsureWeightsFile(test::TestWeightsDir(), 1024 * kWeightsPageBytes);
  REQUIRE(file.ok());
  if (!file->evictable) {
    MESSAGE("skipped: the weights cache " << test::TestWeightsDir() << " is on " << file->fs_type
                                          << ", whose pages only leave memory for swap");
    return;
  }
  Result<MappedWeights> w = MappedWeights::Map(file->path, {});  // prefetched: all resident
  REQUIRE(w.ok());
  (void)Touch(*w);
  const long warm0 = MajorFaults();
  (void)Touch(*w);
  CHECK(MajorFaults() - warm0 == 0);  // resident: a pass costs no I/O
  // What memory pressure does to clean file pages: reclaim them (MADV_PAGEOUT, Linux >= 5.4).
  if (madvise(const_cast<void*>(w->data()), w->bytes(), MADV_PAGEOUT) != 0) {
    MESSAGE("skipped: MADV_PAGEOUT is not available here (" << std::strerror(errno) << ")");
    return;
  }
  const long cold0 = MajorFaults();
  (void)Touch(*w);
  CHECK(MajorFaults() - cold0 > 0);  // refaulted from the file
}

TEST_CASE("the weights read into process memory are not evictable without swap") {
  if (test::EmulatorLauncher::active()) {
    MESSAGE(
        "skipped under qemu-user: page reclaim and fault counts are the host's, not the guest's");
    return;
  }
  Result<WeightsFileInfo> file =
      EnsureWeightsFile(test::TestWeightsDir(), 1024 * kWeightsPageBytes);
  REQUIRE(file.ok());
  WeightsMapOptions read;
  read.load = WeightsLoad::kRead;
  Result<MappedWeights> w = MappedWeights::Map(file->path, read);
  REQUIRE(w.ok());
  if (madvise(const_cast<void*>(w->data()), w->bytes(), MADV_PAGEOUT) != 0) {
    MESSAGE("skipped: MADV_PAGEOUT is not available here (" << std::strerror(errno) << ")");
    return;
  }
  const long f0 = MajorFaults();
  (void)Touch(*w);
  // Anonymous pages stay unless there is swap to write them to.
  std::ifstream swaps("/proc/swaps");
  std::string header, first;
  std::getline(swaps, header);
  if (std::getline(swaps, first) && !first.empty()) {
    MESSAGE("this machine has swap: anonymous pages may be paged out, nothing to assert");
    return;
  }
  CHECK(MajorFaults() - f0 == 0);
}

}  // namespace
}  // namespace zm
