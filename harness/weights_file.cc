// The weights file: creation in the cache directory, and mapping it the way llama.cpp's
// llama_mmap does (or reading it the way Ollama's engine does). See weights_file.h.
#include "harness/weights_file.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statfs.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <utility>
#include <vector>

#include "common/elapsed.h"
#include "harness/control_file.h"
#include "runtime/budget.h"

namespace zm {
namespace {

using Clock = std::chrono::steady_clock;

// The file starts with this header; the rest is a xorshift64 stream from a fixed seed, so the
// content depends only on the size.
struct WeightsHeader {
  std::array<char, 8> magic;
  std::uint64_t bytes;
  std::uint64_t version;
};
constexpr std::array<char, 8> kMagic = {'Z', 'M', 'W', 'E', 'I', 'G', 'H', 'T'};
constexpr std::uint64_t kVersion = 1;
constexpr std::uint64_t kSeed = 0x9E3779B97F4A7C15ULL;
constexpr std::size_t kChunkBytes = 8u << 20;
constexpr std::uint64_t kFreeSpaceMargin = 64ull << 20;

// Closes a descriptor on every path out.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd >= 0) close(fd);
  }
};

std::string FsTypeName(std::int64_t type) {
  switch (static_cast<std::uint64_t>(type) & 0xFFFFFFFFu) {
    case 0xEF53:
      return "ext4";
    case 0x01021994:
      return "tmpfs";
    case 0x858458f6:
      return "ramfs";
    case 0x58465342:
      return "xfs";
    case 0x9123683E:
      return "btrfs";
    case 0x794c7630:
      return "overlay";
    case 0x6969:
      return "nfs";
    case 0x65735546:
      return "fuse";
    default:
      break;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%llx", static_cast<unsigned long long>(type));
  return buf;
}

bool WriteAll(int fd, const void* p, std::size_t n) {
  const char* c = static_cast<const char*>(p);
  while (n > 0) {
    const ssize_t w = write(fd, c, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    c += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

// Writes the content of a `bytes`-long weights file to fd.
Status WriteContent(int fd, std::uint64_t bytes, const std::string& what) {
  std::vector<std::uint64_t> chunk(kChunkBytes / 8);
  std::uint64_t x = kSeed;
  std::uint64_t written = 0;
  bool first = true;
  while (written < bytes) {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(kChunkBytes, bytes - written));
    const std::size_t words = n / 8;
    for (std::size_t i = 0; i < words; ++i) {
      x ^= x << 13;
      x ^= x >> 7;
      x ^= x << 17;
      chunk[i] = x;
    }
    if (first) {
      WeightsHeader h{kMagic, bytes, kVersion};
      std::memcpy(chunk.data(), &h, sizeof h);
      first = false;
    }
    if (!WriteAll(fd, chunk.data(), n)) {
      return IoError("writing " + what + ": " + ErrnoText(errno));
    }
    written += n;
  }
  if (fsync(fd) != 0) return IoError("fsync " + what + ": " + ErrnoText(errno));
  return Status::Ok();
}

}  // namespace

std::string DefaultWeightsDir() {
  if (const char* e = std::getenv("ZM_COTENANT_CACHE"); e != nullptr && *e != '\0') return e;
  if (const char* e = std::getenv("XDG_CACHE_HOME"); e != nullptr && *e != '\0') {
    return std::string(e) + "/zonemap/cotenant";
  }
  if (const char* e = std::getenv("HOME"); e != nullptr && *e != '\0') {
    return std::string(e) + "/.cache/zonemap/cotenant";
  }
  const char* tmp = std::getenv("TMPDIR");
  return std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/zonemap-cotenant-" +
         std::to_string(static_cast<unsigned long>(getuid()));
}

std::string WeightsFileName(std::uint64_t bytes) {
  return "zonemap-cotenant-" + std::to_string(bytes) + ".weights";
}

Result<WeightsFileInfo> EnsureWeightsFile(const std::string& dir_in, std::uint64_t bytes) {
  if (bytes == 0 || bytes % kWeightsPageBytes != 0) {
    return InvalidArgument("weights file size " + std::to_string(bytes) +
                           " must be a positive multiple of " + std::to_string(kWeightsPageBytes));
  }
  const std::string dir = dir_in.empty() ? DefaultWeightsDir() : dir_in;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return IoError("weights cache directory '" + dir + "': " + ec.message());

  WeightsFileInfo info;
  info.path = dir + "/" + WeightsFileName(bytes);
  info.bytes = bytes;
  struct statfs sf {};
  if (statfs(dir.c_str(), &sf) == 0) {
    info.fs_type = FsTypeName(static_cast<std::int64_t>(sf.f_type));
    info.evictable = info.fs_type != "tmpfs" && info.fs_type != "ramfs";
  }

  auto complete = [&]() {
    struct stat st {};
    return stat(info.path.c_str(), &st) == 0 && S_ISREG(st.st_mode) &&
           static_cast<std::uint64_t>(st.st_size) == bytes;
  };
  if (complete()) return info;

  // Serialize creators: the second one finds the file complete once it holds the lock.
  const std::string lock_path = info.path + ".lock";
  Fd lock(open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644));
  if (lock.fd < 0)
    return IoError("weights cache '" + dir + "' is not writable: " + ErrnoText(errno));
  while (flock(lock.fd, LOCK_EX) != 0) {
    if (errno != EINTR) return IoError("locking " + lock_path + ": " + ErrnoText(errno));
  }
  if (complete()) return info;

  struct statvfs vf {};
  if (statvfs(dir.c_str(), &vf) == 0) {
    const std::uint64_t avail = static_cast<std::uint64_t>(vf.f_bavail) * vf.f_frsize;
    if (avail < bytes + kFreeSpaceMargin) {
      return ResourceExhausted("not enough free space in '" + dir + "' for the co-tenant's " +
                               FormatBytes(bytes) + " weights file: " + FormatBytes(avail) +
                               " free, " + FormatBytes(bytes + kFreeSpaceMargin) + " needed");
    }
  }
  const std::string tmp = info.path + ".tmp-" + std::to_string(getpid());
  const auto t0 = Clock::now();
  {
    Fd out(open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (out.fd < 0) return IoError("creating " + tmp + ": " + ErrnoText(errno));
    if (Status s = WriteContent(out.fd, bytes, tmp); !s.ok()) {
      unlink(tmp.c_str());
      return s;
    }
    // Written pages are clean after fsync: let them go, so the reader is charged, not us.
    (void)posix_fadvise(out.fd, 0, 0, POSIX_FADV_DONTNEED);
  }
  if (rename(tmp.c_str(), info.path.c_str()) != 0) {
    const int e = errno;
    unlink(tmp.c_str());
    return IoError("renaming " + tmp + " to " + info.path + ": " + ErrnoText(e));
  }
  if (Fd d(open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)); d.fd >= 0) (void)fsync(d.fd);
  info.created = true;
  info.create_ms = MsSince(t0);
  return info;
}

// ---- MappedWeights ----

MappedWeights::MappedWeights(MappedWeights&& o) noexcept
    : addr_(o.addr_),
      bytes_(o.bytes_),
      file_backed_(o.file_backed_),
      locked_(o.locked_),
      mlock_error_(std::move(o.mlock_error_)),
      load_ms_(o.load_ms_),
      inode_(o.inode_) {
  o.addr_ = nullptr;
  o.bytes_ = 0;
}

MappedWeights& MappedWeights::operator=(MappedWeights&& o) noexcept {
  if (this != &o) {
    Release();
    addr_ = std::exchange(o.addr_, nullptr);
    bytes_ = std::exchange(o.bytes_, 0);
    file_backed_ = o.file_backed_;
    locked_ = o.locked_;
    mlock_error_ = std::move(o.mlock_error_);
    load_ms_ = o.load_ms_;
    inode_ = o.inode_;
  }
  return *this;
}

MappedWeights::~MappedWeights() { Release(); }

void MappedWeights::Release() noexcept {
  if (addr_ != nullptr) munmap(addr_, bytes_);
  addr_ = nullptr;
  bytes_ = 0;
}

int LockPages(const void* addr, std::size_t bytes) noexcept {
  return syscall(SYS_mlock, addr, bytes) == 0 ? 0 : errno;
}

Result<MappedWeights> MappedWeights::Map(const std::string& path,
                                         const WeightsMapOptions& options) {
  const auto t0 = Clock::now();
  Fd fd(open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.fd < 0) return IoError("cannot open weights file '" + path + "': " + ErrnoText(errno));
  struct stat st {};
  if (fstat(fd.fd, &st) != 0) return IoError("stat " + path + ": " + ErrnoText(errno));
  const auto bytes = static_cast<std::uint64_t>(st.st_size);
  WeightsHeader h{};
  if (!S_ISREG(st.st_mode) || bytes < kWeightsPageBytes || bytes % kWeightsPageBytes != 0 ||
      pread(fd.fd, &h, sizeof h, 0) != static_cast<ssize_t>(sizeof h) || h.magic != kMagic ||
      h.bytes != bytes) {
    return Corrupt("'" + path + "' is not a co-tenant weights file of a whole number of pages");
  }
  if (options.cold_start) (void)posix_fadvise(fd.fd, 0, 0, POSIX_FADV_DONTNEED);

  MappedWeights w;
  w.inode_ = st.st_ino;
  const auto size = static_cast<std::size_t>(bytes);
  if (options.load == WeightsLoad::kMmap) {
    // As llama_mmap: sequential read-ahead hint, MAP_SHARED read-only, populated and WILLNEED
    // when prefetching.
    (void)posix_fadvise(fd.fd, 0, 0, POSIX_FADV_SEQUENTIAL);
    const int flags = MAP_SHARED | (options.prefetch ? MAP_POPULATE : 0);
    void* p = mmap(nullptr, size, PROT_READ, flags, fd.fd, 0);
    if (p == MAP_FAILED) {
      return ResourceExhausted("mapping the " + FormatBytes(bytes) + " weights file '" + path +
                               "' failed: " + ErrnoText(errno));
    }
    w.addr_ = p;
    w.bytes_ = size;
    w.file_backed_ = true;
    if (options.prefetch) (void)madvise(p, size, MADV_WILLNEED);
  } else {
    void* p = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) {
      return ResourceExhausted("allocating " + FormatBytes(bytes) +
                               " for the weights failed: " + ErrnoText(errno));
    }
    w.addr_ = p;
    w.bytes_ = size;
    std::size_t done = 0;
    while (done < size) {
      const ssize_t r =
          pread(fd.fd, static_cast<char*>(p) + done, size - done, static_cast<off_t>(done));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0)
        return IoError("reading weights file '" + path + "': " + ErrnoText(r < 0 ? errno : EIO));
      done += static_cast<std::size_t>(r);
    }
    (void)mprotect(p, size, PROT_READ);
  }
  if (options.mlock) {
    // As llama_mlock: on failure raise the soft RLIMIT_MEMLOCK to the hard one and try again;
    // still failing is a warning, not an error.
    if (LockPages(w.addr_, w.bytes_) != 0) {
      struct rlimit rl {};
      if (getrlimit(RLIMIT_MEMLOCK, &rl) == 0 && rl.rlim_cur < rl.rlim_max) {
        rl.rlim_cur = rl.rlim_max;
        (void)setrlimit(RLIMIT_MEMLOCK, &rl);
      }
      if (const int err = LockPages(w.addr_, w.bytes_); err != 0) {
        struct rlimit now {};
        (void)getrlimit(RLIMIT_MEMLOCK, &now);
        const auto limit = [](rlim_t v) {
          return v == RLIM_INFINITY ? std::string("unlimited")
                                    : FormatBytes(static_cast<std::uint64_t>(v));
        };
        w.mlock_error_ = "mlock of " + FormatBytes(bytes) + " failed: " + ErrnoText(err) +
                         " (RLIMIT_MEMLOCK " + limit(now.rlim_cur) + ", hard " +
                         limit(now.rlim_max) + ")";
      }
    }
    w.locked_ = w.mlock_error_.empty();
  }
  w.load_ms_ = MsSince(t0);
  return w;
}

}  // namespace zm
