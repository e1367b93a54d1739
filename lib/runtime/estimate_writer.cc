#include "runtime/estimate_writer.h"

#include <Eigen/Geometry>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "runtime/text_line.h"

namespace zm {
namespace {
constexpr std::size_t kStdioBufferBytes = 1 << 16;
}

EstimateWriter::~EstimateWriter() { Close(); }

Status EstimateWriter::Open(const std::string& path) {
  Close();
  file_ = std::fopen(path.c_str(), "w");
  if (file_ == nullptr) {
    return IoError("cannot open estimate file '" + path + "': " + std::strerror(errno));
  }
  stdio_buffer_ = static_cast<char*>(std::malloc(kStdioBufferBytes));
  if (stdio_buffer_ != nullptr) std::setvbuf(file_, stdio_buffer_, _IOFBF, kStdioBufferBytes);
  std::fputs("# timestamp tx ty tz qx qy qz qw\n", file_);
  return Status::Ok();
}

bool EstimateWriter::Write(double stamp_s, const Pose3& pose) {
  if (file_ == nullptr) return false;
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d& t = pose.translation();
  char line[256];
  TextLine l(line, sizeof line);
  l.Fixed(stamp_s, 6).Sp().Fixed(t.x(), 6).Sp().Fixed(t.y(), 6).Sp().Fixed(t.z(), 6);
  l.Sp().Fixed(q.x(), 9).Sp().Fixed(q.y(), 9).Sp().Fixed(q.z(), 9).Sp().Fixed(q.w(), 9).Char('\n');
  return l.ok() && std::fwrite(line, 1, l.size(), file_) == l.size();
}

void EstimateWriter::Flush() {
  if (file_ != nullptr) std::fflush(file_);
}

void EstimateWriter::Close() {
  if (file_ != nullptr) {
    std::fclose(file_);
    file_ = nullptr;
  }
  std::free(stdio_buffer_);
  stdio_buffer_ = nullptr;
}

}  // namespace zm
