// The co-tenant's weights as a model server keeps them: a file, created once in a cache directory
// (real pseudo-random bytes, not a sparse file, whose holes would not be page cache worth the
// name) and reused by every later run, then mapped read-only and shared like llama.cpp's
// llama_mmap (MAP_SHARED, PROT_READ, POSIX_FADV_SEQUENTIAL; MAP_POPULATE + MADV_WILLNEED when
// prefetching; mlock on request), or read into process memory like Ollama's own engine.
//
// Invariants:
//   - A file under its final name is complete: it is written under a temporary name, fsync'ed
//     and renamed; concurrent creators serialize on "<name>.lock".
//   - After creating the file, its pages are dropped from the page cache, so the first process
//     that reads it is the one charged for them (a memory cgroup charges page cache to the
//     cgroup that faulted it in).
//   - MappedWeights releases its mapping (munmap) on destruction; nothing is written to the file
//     after creation.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "common/status.h"
#include "harness/cotenant_options.h"

namespace zm {

inline constexpr std::uint64_t kWeightsPageBytes = 4096;  // weights sizes are rounded to this

// $ZM_COTENANT_CACHE, else $XDG_CACHE_HOME/zonemap/cotenant, else $HOME/.cache/zonemap/cotenant,
// else $TMPDIR (or /tmp)/zonemap-cotenant-<uid>.
[[nodiscard]] std::string DefaultWeightsDir();
// "zonemap-cotenant-<bytes>.weights": the content depends only on the size, so every model of one
// size shares a file.
[[nodiscard]] std::string WeightsFileName(std::uint64_t bytes);

struct WeightsFileInfo {
  std::string path;
  std::uint64_t bytes = 0;
  bool created = false;    // false: reused from an earlier run
  double create_ms = 0.0;  // writing it (0 when reused)
  std::string fs_type;     // "ext4", "tmpfs", ... (statfs)
  bool evictable = true;   // false on tmpfs/ramfs: shmem pages only leave memory for swap
};

// The weights file of `bytes` (a multiple of kWeightsPageBytes, > 0) in `dir` (empty =
// DefaultWeightsDir()), created if absent. Errors name the directory and what failed (not
// writable, not enough free space: the check happens before writing).
[[nodiscard]] Result<WeightsFileInfo> EnsureWeightsFile(const std::string& dir,
                                                        std::uint64_t bytes);

// mlock(2) through the system call itself: 0 or an errno. The sanitizers intercept mlock() as a
// no-op that returns 0, which would report memory as pinned that is not (and hide a refusal).
[[nodiscard]] int LockPages(const void* addr, std::size_t bytes) noexcept;

struct WeightsMapOptions {
  WeightsLoad load = WeightsLoad::kMmap;
  bool prefetch = true;
  bool mlock = false;
  bool cold_start = true;  // POSIX_FADV_DONTNEED on the file before mapping (unmapped pages only)
};

// The weights in memory. Move-only.
class MappedWeights {
 public:
  MappedWeights() = default;
  MappedWeights(MappedWeights&& other) noexcept;
  MappedWeights& operator=(MappedWeights&& other) noexcept;
  MappedWeights(const MappedWeights&) = delete;
  MappedWeights& operator=(const MappedWeights&) = delete;
  ~MappedWeights();

  // Maps (or reads) the file at `path`. Errors: the file cannot be opened or is not a weights
  // file of a whole number of pages, the kernel refuses the mapping (e.g. RLIMIT_AS), a read fails.
  [[nodiscard]] static Result<MappedWeights> Map(const std::string& path,
                                                 const WeightsMapOptions& options);

  [[nodiscard]] const std::uint64_t* words() const noexcept {
    return static_cast<const std::uint64_t*>(addr_);
  }
  [[nodiscard]] std::size_t bytes() const noexcept { return bytes_; }
  [[nodiscard]] const void* data() const noexcept { return addr_; }
  [[nodiscard]] bool file_backed() const noexcept { return file_backed_; }
  [[nodiscard]] bool locked() const noexcept { return locked_; }
  // Why mlock failed (llama.cpp warns and carries on; so does this), empty otherwise.
  [[nodiscard]] const std::string& mlock_error() const noexcept { return mlock_error_; }
  [[nodiscard]] double load_ms() const noexcept { return load_ms_; }
  [[nodiscard]] ino_t inode() const noexcept { return inode_; }

 private:
  void Release() noexcept;

  void* addr_ = nullptr;
  std::size_t bytes_ = 0;
  bool file_backed_ = false;
  bool locked_ = false;
  std::string mlock_error_;
  double load_ms_ = 0.0;
  ino_t inode_ = 0;
};

}  // namespace zm
