// Line readers over a file descriptor and a UDP socket (see line_input.h).
#include "runtime/line_input.h"

#include <arpa/inet.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>

namespace zm {

FdLineReader::FdLineReader(int fd, std::size_t capacity)
    : fd_(fd), buf_(std::make_unique<char[]>(std::max<std::size_t>(capacity, 64))),
      cap_(std::max<std::size_t>(capacity, 64)) {}

namespace {
// Input is readable now (or the descriptor is at its end or broken: a read would not block).
bool Readable(int fd) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, 0) > 0;
}
}  // namespace

bool FdLineReader::Waiting() const {
  if (eof_) return begin_ < end_;
  if (std::memchr(buf_.get() + begin_, '\n', end_ - begin_) != nullptr) return true;
  return Readable(fd_);
}

bool UdpLineReader::Waiting() const { return begin_ < end_ || Readable(fd_); }

Result<LineRead> FdLineReader::NextLine(std::string_view* line) {
  for (;;) {
    // A complete line in the buffer?
    const char* base = buf_.get();
    const char* nl = static_cast<const char*>(std::memchr(base + begin_, '\n', end_ - begin_));
    if (nl == nullptr && eof_ && begin_ < end_) nl = base + end_;  // last line, no newline
    if (nl != nullptr) {
      *line = std::string_view(base + begin_, static_cast<std::size_t>(nl - (base + begin_)));
      begin_ = std::min(end_, static_cast<std::size_t>(nl - base) + 1);
      if (skipping_long_line_) {  // the tail of a line already reported as too long
        skipping_long_line_ = false;
        continue;
      }
      return LineRead::kLine;
    }
    if (eof_) return LineRead::kEnd;
    // Compact, then read more.
    if (begin_ > 0) {
      std::memmove(buf_.get(), buf_.get() + begin_, end_ - begin_);
      end_ -= begin_;
      begin_ = 0;
    }
    bool too_long = false;
    if (end_ == cap_) {  // a line longer than any valid one: drop it, report it once
      too_long = !skipping_long_line_;
      skipping_long_line_ = true;
      end_ = 0;
    }
    const ssize_t n = ::read(fd_, buf_.get() + end_, cap_ - end_);
    if (n < 0) {
      if (errno == EINTR) return LineRead::kEnd;  // a signal asked the loop to stop
      return IoError(std::string("reading the line protocol: ") + std::strerror(errno));
    }
    if (n == 0) eof_ = true;
    end_ += static_cast<std::size_t>(n);
    if (too_long) return LineRead::kTooLong;
  }
}

Result<std::unique_ptr<UdpLineReader>> UdpLineReader::Bind(std::uint16_t port,
                                                           std::size_t capacity) {
  std::unique_ptr<UdpLineReader> s(new UdpLineReader());
  s->fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
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
  // A UDP datagram carries at most 65,507 bytes of payload.
  s->cap_ = std::clamp<std::size_t>(capacity, 64, 65507);
  s->buf_ = std::make_unique<char[]>(s->cap_);
  return s;
}

UdpLineReader::~UdpLineReader() {
  if (fd_ >= 0) ::close(fd_);
}

Result<LineRead> UdpLineReader::NextLine(std::string_view* line) {
  for (;;) {
    if (begin_ < end_) {
      const char* base = buf_.get();
      const char* nl = static_cast<const char*>(std::memchr(base + begin_, '\n', end_ - begin_));
      const char* stop = nl != nullptr ? nl : base + end_;
      *line = std::string_view(base + begin_, static_cast<std::size_t>(stop - (base + begin_)));
      begin_ = static_cast<std::size_t>(stop - base) + 1;
      if (line->empty() && nl != nullptr && begin_ >= end_) continue;  // the datagram's final '\n'
      return LineRead::kLine;
    }
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    const ssize_t n = ::recvfrom(fd_, buf_.get(), cap_, MSG_TRUNC,
                                 reinterpret_cast<sockaddr*>(&from), &from_len);
    if (n < 0) {
      if (errno == EINTR) return LineRead::kEnd;
      return IoError(std::string("udp recv: ") + std::strerror(errno));
    }
    peer_ = from;
    has_peer_ = true;
    if (n == 0) return LineRead::kEnd;  // an empty datagram ends the stream
    if (static_cast<std::size_t>(n) > cap_) {
      begin_ = end_ = 0;
      return LineRead::kTooLong;
    }
    begin_ = 0;
    end_ = static_cast<std::size_t>(n);
  }
}

bool UdpLineReader::Reply(std::string_view bytes) {
  if (!has_peer_) return false;
  const ssize_t n = ::sendto(fd_, bytes.data(), bytes.size(), MSG_DONTWAIT,
                             reinterpret_cast<const sockaddr*>(&peer_), sizeof peer_);
  return n == static_cast<ssize_t>(bytes.size());
}

}  // namespace zm
