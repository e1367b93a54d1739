// Kernel control files: see control_file.h.
#include "harness/control_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace zm {
namespace {

std::string Prefix(std::string_view who) { return who.empty() ? "" : std::string(who) + ": "; }

std::string Described(const std::string& value, std::string_view what) {
  return what.empty() ? value : value + " (" + std::string(what) + ")";
}

}  // namespace

std::string ErrnoText(int err) { return std::strerror(err); }

Result<std::string> ReadControlFile(const std::string& path, std::string_view who) {
  std::ifstream in(path);
  if (!in) return IoError(Prefix(who) + "cannot read " + path + ": " + ErrnoText(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Status WriteControlFile(const std::string& path, const std::string& value, std::string_view who,
                        std::string_view what) {
  const int fd = open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (fd < 0) {
    return IoError(Prefix(who) + "cannot open " + path + " to write " + Described(value, what) +
                   ": " + ErrnoText(errno));
  }
  const ssize_t n = write(fd, value.data(), value.size());
  const int err = errno;
  close(fd);
  if (n != static_cast<ssize_t>(value.size())) {
    return IoError(Prefix(who) + "writing " + Described(value, what) + " to " + path +
                   " failed: " + ErrnoText(n < 0 ? err : EIO));
  }
  return Status::Ok();
}

bool PathExists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

}  // namespace zm
