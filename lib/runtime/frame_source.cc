#include "runtime/frame_source.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include "runtime/frames_file.h"

namespace zm {
namespace {

// Bytes for one line of `max_features` features: 3 numbers + 64 hex digits each, plus the pose.
std::size_t LineBytesFor(std::uint32_t max_features) {
  return 512 + std::size_t{max_features} * (2 * 24 + 2 * kDescriptorBytes + 3);
}

class ReplayFrameSource final : public FrameSource {
 public:
  explicit ReplayFrameSource(FrameReader reader) : reader_(std::move(reader)) {}
  Result<bool> Next(Frame* frame) override { return reader_.Next(frame); }
  [[nodiscard]] std::uint32_t max_features() const override { return reader_.max_features(); }

 private:
  FrameReader reader_;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenReplaySource(const std::string& frames_path) {
  auto reader = FrameReader::Open(frames_path);
  if (!reader.ok()) return reader.status();
  return std::unique_ptr<FrameSource>(new ReplayFrameSource(std::move(reader).value()));
}

LineFrameSource::LineFrameSource(int fd, std::uint32_t max_features)
    : fd_(fd), max_features_(max_features), cap_(LineBytesFor(max_features)) {
  buf_ = std::make_unique<char[]>(cap_);
}

namespace {
// Input is readable now (or the descriptor is at its end or broken: Next() would not block).
bool Readable(int fd) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, 0) > 0;
}
}  // namespace

bool LineFrameSource::FrameWaiting() {
  if (eof_) return false;
  if (std::memchr(buf_.get() + begin_, '\n', end_ - begin_) != nullptr) return true;
  return Readable(fd_);
}

bool UdpFrameSource::FrameWaiting() { return Readable(fd_); }

Result<bool> LineFrameSource::Next(Frame* frame) {
  for (;;) {
    // A complete line in the buffer?
    const char* nl = static_cast<const char*>(std::memchr(buf_.get() + begin_, '\n', end_ - begin_));
    if (nl == nullptr && eof_ && begin_ < end_) nl = buf_.get() + end_;  // last line, no newline
    if (nl != nullptr) {
      const std::string_view line(buf_.get() + begin_, static_cast<std::size_t>(nl - (buf_.get() + begin_)));
      begin_ = std::min(end_, static_cast<std::size_t>(nl - buf_.get()) + 1);
      if (skipping_long_line_) {
        skipping_long_line_ = false;
        continue;
      }
      const LineKind kind = ParseFrameLine(line, max_features_, frame, &last_error_);
      if (kind == LineKind::kFrame) {
        frame->index = next_index_++;
        return true;
      }
      if (kind == LineKind::kMalformed) ++malformed_;
      continue;
    }
    if (eof_) return false;
    // Compact, then read more.
    if (begin_ > 0) {
      std::memmove(buf_.get(), buf_.get() + begin_, end_ - begin_);
      end_ -= begin_;
      begin_ = 0;
    }
    if (end_ == cap_) {  // a line longer than any valid frame: drop it, count it once
      ++malformed_;
      last_error_ = {"line longer than the largest valid frame", cap_};
      skipping_long_line_ = true;
      end_ = 0;
    }
    const ssize_t n = ::read(fd_, buf_.get() + end_, cap_ - end_);
    if (n < 0) {
      if (errno == EINTR) return false;  // a signal asked the loop to stop
      return IoError(std::string("reading frames: ") + std::strerror(errno));
    }
    if (n == 0) eof_ = true;
    end_ += static_cast<std::size_t>(n);
  }
}

Result<std::unique_ptr<UdpFrameSource>> UdpFrameSource::Bind(std::uint16_t port,
                                                             std::uint32_t max_features) {
  std::unique_ptr<UdpFrameSource> s(new UdpFrameSource());
  s->fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (s->fd_ < 0) return IoError(std::string("udp socket: ") + std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(s->fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    return IoError("udp bind 127.0.0.1:" + std::to_string(port) + ": " + std::strerror(errno));
  }
  socklen_t len = sizeof addr;
  ::getsockname(s->fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  s->port_ = ntohs(addr.sin_port);
  s->max_features_ = max_features;
  s->cap_ = LineBytesFor(max_features);
  s->buf_ = std::make_unique<char[]>(s->cap_);
  return s;
}

UdpFrameSource::~UdpFrameSource() {
  if (fd_ >= 0) ::close(fd_);
}

Result<bool> UdpFrameSource::Next(Frame* frame) {
  for (;;) {
    const ssize_t n = ::recv(fd_, buf_.get(), cap_, MSG_TRUNC);
    if (n < 0) {
      if (errno == EINTR) return false;
      return IoError(std::string("udp recv: ") + std::strerror(errno));
    }
    if (n == 0) return false;
    if (static_cast<std::size_t>(n) > cap_) {
      ++malformed_;
      continue;
    }
    std::string_view line(buf_.get(), static_cast<std::size_t>(n));
    while (!line.empty() && line.back() == '\n') line.remove_suffix(1);
    LineError err;
    const LineKind kind = ParseFrameLine(line, max_features_, frame, &err);
    if (kind == LineKind::kFrame) {
      frame->index = next_index_++;
      return true;
    }
    if (kind == LineKind::kMalformed) ++malformed_;
  }
}

}  // namespace zm
