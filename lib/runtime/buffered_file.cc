// The buffered output file (see buffered_file.h).
#include "runtime/buffered_file.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace zm {
namespace {
constexpr std::size_t kStdioBufferBytes = 1 << 16;
}

Status BufferedFile::Open(const std::string& path, std::string_view what) {
  Close();
  file_ = std::fopen(path.c_str(), "w");
  if (file_ == nullptr) {
    return IoError("cannot open " + std::string(what) + " '" + path + "': " + std::strerror(errno));
  }
  buffer_ = static_cast<char*>(std::malloc(kStdioBufferBytes));
  if (buffer_ != nullptr) std::setvbuf(file_, buffer_, _IOFBF, kStdioBufferBytes);
  return Status::Ok();
}

bool BufferedFile::Write(std::string_view bytes) {
  if (file_ == nullptr) return false;
  return std::fwrite(bytes.data(), 1, bytes.size(), file_) == bytes.size();
}

void BufferedFile::Flush() {
  if (file_ != nullptr) std::fflush(file_);
}

void BufferedFile::Close() {
  if (file_ != nullptr) {
    std::fclose(file_);
    file_ = nullptr;
  }
  std::free(buffer_);
  buffer_ = nullptr;
}

}  // namespace zm
