// BufferedFile (buffered_file.h).
#include "runtime/buffered_file.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace zm {
namespace {
// 64 KiB: a few hundred telemetry lines between flushes without a write(2) each.
constexpr std::size_t kStdioBufferBytes = 1 << 16;
}  // namespace

BufferedFile::~BufferedFile() { Close(); }

Status BufferedFile::Open(const std::string& path, std::string_view what) {
  Close();
  file_ = std::fopen(path.c_str(), "w");
  if (file_ == nullptr) {
    return IoError("cannot open " + std::string(what) + " '" + path + "': " + std::strerror(errno));
  }
  stdio_buffer_ = static_cast<char*>(std::malloc(kStdioBufferBytes));
  if (stdio_buffer_ != nullptr) std::setvbuf(file_, stdio_buffer_, _IOFBF, kStdioBufferBytes);
  return Status::Ok();
}

bool BufferedFile::Write(std::string_view bytes) {
  return file_ != nullptr && std::fwrite(bytes.data(), 1, bytes.size(), file_) == bytes.size();
}

void BufferedFile::Flush() {
  if (file_ != nullptr) std::fflush(file_);
}

void BufferedFile::Close() {
  if (file_ != nullptr) {
    std::fclose(file_);
    file_ = nullptr;
  }
  std::free(stdio_buffer_);
  stdio_buffer_ = nullptr;
}

}  // namespace zm
