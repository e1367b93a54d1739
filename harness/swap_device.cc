// The device's zram swap. See swap_device.h.
#include "harness/swap_device.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/swap.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>
#include <utility>

#include "harness/control_file.h"
#include "harness/process_sample.h"
#include "runtime/budget.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

// nvzramconfig's `swapon -p 5`: above a disk swap, as JetPack sets it.
constexpr int kZramSwapPriority = 5;

std::string Trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

std::string BlockDir(const SwapSystem& sys, int id) {
  return sys.sysfs_root + "/block/zram" + std::to_string(id);
}
std::string DevPath(const SwapSystem& sys, int id) {
  return sys.dev_root + "/zram" + std::to_string(id);
}
std::string RecordPath(const SwapSystem& sys, int id) {
  return sys.owner_dir + "/zram-" + std::to_string(id);
}

int DefaultSwapOn(const std::string& path, int priority) {
  const int flags = SWAP_FLAG_PREFER | ((priority << SWAP_FLAG_PRIO_SHIFT) & SWAP_FLAG_PRIO_MASK);
  return ::swapon(path.c_str(), flags) == 0 ? 0 : errno;
}
int DefaultSwapOff(const std::string& path) { return ::swapoff(path.c_str()) == 0 ? 0 : errno; }

SwapSystem WithDefaults(SwapSystem sys) {
  if (!sys.swap_on) sys.swap_on = DefaultSwapOn;
  if (!sys.swap_off) sys.swap_off = DefaultSwapOff;
  return sys;
}

bool IsSwapActive(const SwapSystem& sys, const std::string& path) {
  auto text = ReadControlFile(sys.proc_swaps);
  return text.ok() && ProcSwapsContains(*text, path);
}

// swapoff (when it is a swap), reset, hot_remove, record removed: a device this module made.
Status RemoveZram(const SwapSystem& sys, int id) {
  const std::string dev = DevPath(sys, id);
  const std::string name = "zram" + std::to_string(id);
  if (IsSwapActive(sys, dev)) {
    if (const int e = sys.swap_off(dev); e != 0) {
      return IoError("swap: swapoff " + dev + " failed: " + ErrnoText(e) +
                     " (its pages must fit back in memory)");
    }
  }
  if (PathExists(BlockDir(sys, id))) {
    ZM_RETURN_IF_ERROR(
        WriteControlFile(BlockDir(sys, id) + "/reset", "1").Annotate("swap: reset " + name));
    // The kernel may hold the device busy for a moment after swapoff.
    Status removed;
    for (int attempt = 0; attempt < 100; ++attempt) {
      removed =
          WriteControlFile(sys.sysfs_root + "/class/zram-control/hot_remove", std::to_string(id));
      if (removed.ok()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ZM_RETURN_IF_ERROR(removed.Annotate("swap: hot_remove " + name));
  }
  std::error_code ec;
  fs::remove(RecordPath(sys, id), ec);
  return Status::Ok();
}

// The id a "zram-<id>" record names; -1 for other names.
int RecordId(std::string_view name) {
  constexpr std::string_view kPrefix = "zram-";
  if (name.substr(0, kPrefix.size()) != kPrefix) return -1;
  const std::string_view num = name.substr(kPrefix.size());
  int id = -1;
  const auto [end, ec] = std::from_chars(num.data(), num.data() + num.size(), id);
  return ec == std::errc() && end == num.data() + num.size() && id >= 0 ? id : -1;
}

bool PreadMmStat(int fd, ZramSample* out) noexcept {
  if (fd < 0) return false;
  char buf[256];
  const ssize_t n = pread(fd, buf, sizeof buf - 1, 0);
  if (n <= 0) return false;
  const char* p = buf;
  const char* end = buf + n;
  std::uint64_t v[3] = {0, 0, 0};
  for (std::uint64_t& x : v) {
    while (p < end && *p == ' ') ++p;
    const auto [q, ec] = std::from_chars(p, end, x);
    if (ec != std::errc()) return false;
    p = q;
  }
  out->orig_data_bytes = v[0];
  out->compr_data_bytes = v[1];
  out->mem_used_bytes = v[2];
  out->ok = true;
  return true;
}

}  // namespace

std::string_view SwapKindName(SwapKind kind) {
  switch (kind) {
    case SwapKind::kZram:
      return "zram";
    case SwapKind::kExisting:
      return "existing";
    case SwapKind::kNone:
      break;
  }
  return "none";
}

ActiveSwaps ParseProcSwaps(std::string_view text) {
  ActiveSwaps a;
  std::size_t pos = text.find('\n');  // the header line
  while (pos != std::string_view::npos && pos + 1 < text.size()) {
    const std::size_t start = pos + 1;
    pos = text.find('\n', start);
    const std::string_view line =
        text.substr(start, pos == std::string_view::npos ? std::string_view::npos : pos - start);
    // Filename Type Size(KiB) Used Priority
    std::string_view fields[3];
    std::size_t n = 0, i = 0;
    while (i < line.size() && n < 3) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      const std::size_t b = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
      if (i > b) fields[n++] = line.substr(b, i - b);
    }
    if (n < 3) continue;
    std::uint64_t kib = 0;
    (void)std::from_chars(fields[2].data(), fields[2].data() + fields[2].size(), kib);
    if (a.count == 0) a.first = std::string(fields[0]);
    ++a.count;
    a.total_bytes += kib * 1024;
  }
  return a;
}

bool ProcSwapsContains(std::string_view text, std::string_view path) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view line = text.substr(pos, eol - pos);
    if (line.size() > path.size() && line.substr(0, path.size()) == path &&
        (line[path.size()] == ' ' || line[path.size()] == '\t')) {
      return true;
    }
    pos = eol + 1;
  }
  return false;
}

Result<std::string> SwapHeaderPage(std::uint64_t bytes, std::uint32_t page_bytes) {
  if (page_bytes < 4096 || (page_bytes & (page_bytes - 1)) != 0) {
    return InvalidArgument("swap header: page size " + std::to_string(page_bytes) +
                           " is not a power of two >= 4096");
  }
  const std::uint64_t pages = bytes / page_bytes;
  // The kernel wants more than the header page; mkswap refuses fewer than 10 pages.
  if (pages < 10 || pages - 1 > 0xFFFFFFFFULL) {
    return InvalidArgument("swap header: " + FormatBytes(bytes) + " is " + std::to_string(pages) +
                           " pages; a swap needs 10 to 2^32 pages");
  }
  std::string page(page_bytes, '\0');
  const std::uint32_t version = 1, last_page = static_cast<std::uint32_t>(pages - 1), bad = 0;
  std::memcpy(page.data() + 1024, &version, 4);
  std::memcpy(page.data() + 1028, &last_page, 4);
  std::memcpy(page.data() + 1032, &bad, 4);
  std::random_device rd;
  for (std::size_t i = 0; i < 16; ++i) page[1036 + i] = static_cast<char>(rd() & 0xFF);
  page[1036 + 6] = static_cast<char>((page[1036 + 6] & 0x0F) | 0x40);  // UUID version 4
  page[1036 + 8] = static_cast<char>((page[1036 + 8] & 0x3F) | 0x80);  // RFC 4122 variant
  std::memcpy(page.data() + 1052, "zonemap", 7);                       // volume label
  std::memcpy(page.data() + page_bytes - 10, "SWAPSPACE2", 10);
  return page;
}

Result<std::uint32_t> RemoveStaleZramDevices(const SwapSystem& system) {
  const SwapSystem sys = WithDefaults(system);
  std::error_code ec;
  if (!fs::is_directory(sys.owner_dir, ec)) return std::uint32_t{0};
  std::uint32_t removed = 0;
  Status first_error;
  for (const fs::directory_entry& e : fs::directory_iterator(sys.owner_dir, ec)) {
    const int id = RecordId(e.path().filename().string());
    if (id < 0) continue;
    long pid = 0;
    unsigned long long start = 0;
    {
      std::ifstream in(e.path());
      in >> pid >> start;
    }
    if (pid > 0 && ProcessStartTicks(static_cast<pid_t>(pid)) == start) continue;  // alive
    Status s = RemoveZram(sys, id);
    if (s.ok()) {
      ++removed;
    } else if (first_error.ok()) {
      first_error = s.Annotate("removing the stale zram" + std::to_string(id) + " of pid " +
                               std::to_string(pid));
    }
  }
  if (!first_error.ok()) return first_error;
  return removed;
}

DeviceSwap OpenDeviceSwap(const SwapOptions& options) {
  DeviceSwap s;
  s.system_ = WithDefaults(options.system);
  const SwapSystem& sys = s.system_;
  if (options.requested == "none") {
    s.reason_ = "the profile's device.swap is none";
    return s;
  }
  if (options.requested != "zram") {
    s.reason_ = "device.swap '" + options.requested + "' is not none or zram";
    return s;
  }
  if (options.bytes == 0) {
    s.reason_ = "device.swap_bytes is 0";
    return s;
  }
  if (auto stale = RemoveStaleZramDevices(sys); !stale.ok()) {
    std::fprintf(stderr, "device swap: %s\n", stale.status().message().c_str());
  } else if (*stale > 0) {
    std::fprintf(stderr, "device swap: removed %u stale zram device(s) of earlier runs\n", *stale);
  }
  // A real Jetson: JetPack's zram is already on; the device cgroup's swap limit is the profile's.
  if (auto text = ReadControlFile(sys.proc_swaps); text.ok()) {
    const ActiveSwaps active = ParseProcSwaps(*text);
    if (active.count > 0) {
      s.kind_ = SwapKind::kExisting;
      s.bytes_ = options.bytes;
      s.device_path_ = active.first;
      if (active.total_bytes < options.bytes) {
        s.reason_ = "the active swap (" + FormatBytes(active.total_bytes) +
                    ") is smaller than device.swap_bytes (" + FormatBytes(options.bytes) + ")";
      }
      return s;
    }
  }
  const auto fall_back = [&s](std::string why) -> DeviceSwap {
    const int id = s.zram_id_;
    if (id >= 0) {
      if (Status r = RemoveZram(s.system_, id); !r.ok()) why += "; and " + r.message();
    }
    s.zram_id_ = -1;
    s.swapped_on_ = false;
    s.device_path_.clear();
    s.kind_ = SwapKind::kNone;
    s.bytes_ = 0;
    s.reason_ = std::move(why);
    return std::move(s);
  };
  const std::string hot_add = sys.sysfs_root + "/class/zram-control/hot_add";
  auto added = ReadControlFile(hot_add);  // reading it makes a device and returns its id
  int id = -1;
  if (added.ok()) {
    const std::string t = Trim(*added);
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), id);
    if (ec != std::errc() || end != t.data() + t.size()) id = -1;
  }
  if (id < 0) {
    return fall_back(
        "cannot hot-add a zram device (" +
        (added.ok() ? hot_add + " gave '" + Trim(*added) + "'" : added.status().message()) +
        "): no zram module, or not root");
  }
  s.zram_id_ = id;
  // The owner record first: a crash from here on leaves a device the next run removes.
  {
    std::error_code ec;
    fs::create_directories(sys.owner_dir, ec);
    std::ofstream rec(RecordPath(sys, id));
    rec << getpid() << ' ' << ProcessStartTicks(getpid()) << '\n';
    rec.flush();
    if (ec || !rec) {
      return fall_back("cannot write the owner record " + RecordPath(sys, id) +
                       (ec ? ": " + ec.message() : std::string()));
    }
  }
  const std::string block = BlockDir(sys, id);
  if (auto algs = ReadControlFile(block + "/comp_algorithm"); algs.ok()) {
    // "[lzo-rle] lzo lz4 ...": the bracketed one is current.
    std::istringstream in(*algs);
    std::string tok, current;
    bool lz4 = false;
    while (in >> tok) {
      if (tok.front() == '[') {
        tok = tok.substr(1, tok.size() - 2);
        current = tok;
      }
      lz4 = lz4 || tok == "lz4";
    }
    s.comp_algorithm_ = current;
    if (lz4 && WriteControlFile(block + "/comp_algorithm", "lz4").ok()) s.comp_algorithm_ = "lz4";
  }
  const auto page = static_cast<std::uint32_t>(sysconf(_SC_PAGESIZE));
  const std::uint64_t bytes = options.bytes / page * page;
  if (Status d = WriteControlFile(block + "/disksize", std::to_string(bytes)); !d.ok()) {
    return fall_back("zram" + std::to_string(id) + ": " + d.message());
  }
  s.device_path_ = DevPath(sys, id);
  {
    auto header = SwapHeaderPage(bytes, page);
    if (!header.ok()) return fall_back(header.status().message());
    int fd = -1;
    // devtmpfs makes the node as the device appears; allow it a moment.
    for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
      fd = open(s.device_path_.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd < 0 && errno != ENOENT) break;
      if (fd < 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (fd < 0) return fall_back("cannot open " + s.device_path_ + ": " + ErrnoText(errno));
    const ssize_t n = write(fd, header->data(), header->size());
    const int err = errno;
    const bool synced = fsync(fd) == 0;
    close(fd);
    if (n != static_cast<ssize_t>(header->size()) || !synced) {
      return fall_back("writing the swap header to " + s.device_path_ +
                       " failed: " + ErrnoText(n < 0 ? err : EIO));
    }
  }
  if (const int e = sys.swap_on(s.device_path_, kZramSwapPriority); e != 0) {
    return fall_back("swapon " + s.device_path_ + " refused: " + ErrnoText(e));
  }
  s.swapped_on_ = true;
  s.kind_ = SwapKind::kZram;
  s.bytes_ = bytes;
  s.mm_stat_fd_ = open((block + "/mm_stat").c_str(), O_RDONLY | O_CLOEXEC);
  return s;
}

DeviceSwap::DeviceSwap(DeviceSwap&& other) noexcept { *this = std::move(other); }

DeviceSwap& DeviceSwap::operator=(DeviceSwap&& other) noexcept {
  if (this != &other) {
    (void)Remove();
    kind_ = std::exchange(other.kind_, SwapKind::kNone);
    bytes_ = std::exchange(other.bytes_, 0);
    reason_ = std::move(other.reason_);
    device_path_ = std::move(other.device_path_);
    comp_algorithm_ = std::move(other.comp_algorithm_);
    zram_id_ = std::exchange(other.zram_id_, -1);
    swapped_on_ = std::exchange(other.swapped_on_, false);
    mm_stat_fd_ = std::exchange(other.mm_stat_fd_, -1);
    system_ = std::move(other.system_);
  }
  return *this;
}

DeviceSwap::~DeviceSwap() { (void)Remove(); }

std::string DeviceSwap::Describe() const {
  switch (kind_) {
    case SwapKind::kZram:
      return "zram " + device_path_ + " " + FormatBytes(bytes_) + " (" + comp_algorithm_ +
             ", priority " + std::to_string(kZramSwapPriority) + ", made for this run)";
    case SwapKind::kExisting:
      return "the active swap " + device_path_ + ", device limit " + FormatBytes(bytes_) +
             (reason_.empty() ? "" : " (" + reason_ + ")");
    case SwapKind::kNone:
      break;
  }
  return "no swap (" + reason_ + ")";
}

ZramSample DeviceSwap::Sample() const noexcept {
  ZramSample z;
  (void)PreadMmStat(mm_stat_fd_, &z);
  return z;
}

Status DeviceSwap::Remove() {
  if (mm_stat_fd_ >= 0) close(mm_stat_fd_);
  mm_stat_fd_ = -1;
  if (zram_id_ < 0) return Status::Ok();
  const int id = std::exchange(zram_id_, -1);
  swapped_on_ = false;
  return RemoveZram(system_, id);
}

}  // namespace zm
