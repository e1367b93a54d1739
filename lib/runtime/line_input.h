// Where the live protocol's lines come from (line_protocol.h), one line at a time, from a buffer
// allocated once at construction:
//   FdLineReader   a byte stream (stdin, a pipe): lines end at '\n'; the last one may not;
//   UdpLineReader  a loopback UDP socket: each datagram holds one or more lines; replies go
//                  back to the datagram's sender (Reply), which is how --udp answers a robot.
// A line longer than the buffer (MaxInputLineBytes) is dropped whole and reported once as
// RejectReason::kLineTooLong: the reader never grows. A signal (EINTR) ends the input, so
// SIGINT/SIGTERM stop a daemon blocked in read() at once (stop_signal.h).
#pragma once

#include <netinet/in.h>

#include <cstdint>
#include <memory>
#include <string_view>

#include "common/status.h"

namespace zm {

// What NextLine() found.
enum class LineRead { kLine, kTooLong, kEnd };

class FdLineReader {
 public:
  // Reads `fd` (not owned) into a buffer of `capacity` bytes (the longest line accepted).
  FdLineReader(int fd, std::size_t capacity);
  // kLine: *line holds it (without '\n'), valid until the next call. kTooLong: a line longer
  // than the buffer was skipped. kEnd: end of file or a signal. Errors: read() failed.
  [[nodiscard]] Result<LineRead> NextLine(std::string_view* line);
  // A whole line is buffered, or the descriptor is readable (or at its end): NextLine() would
  // not block. Never blocks.
  [[nodiscard]] bool Waiting() const;

 private:
  int fd_;
  std::unique_ptr<char[]> buf_;
  std::size_t cap_, begin_ = 0, end_ = 0;
  bool eof_ = false;
  bool skipping_long_line_ = false;
};

class UdpLineReader {
 public:
  // Binds 127.0.0.1:port (loopback only; 0 = any free port, see port()). Datagrams up to
  // `capacity` bytes; longer ones are dropped (kTooLong). An empty datagram ends the input.
  [[nodiscard]] static Result<std::unique_ptr<UdpLineReader>> Bind(std::uint16_t port,
                                                                   std::size_t capacity);
  ~UdpLineReader();
  UdpLineReader(const UdpLineReader&) = delete;
  UdpLineReader& operator=(const UdpLineReader&) = delete;

  // As FdLineReader::NextLine; the lines of one datagram come one after the other.
  [[nodiscard]] Result<LineRead> NextLine(std::string_view* line);
  // Lines of the current datagram left, or a datagram waiting. Never blocks.
  [[nodiscard]] bool Waiting() const;
  // Sends `bytes` as one datagram to the sender of the current datagram. false if there is no
  // sender yet or the send failed (the robot is gone: counted by the caller, never fatal).
  bool Reply(std::string_view bytes);
  [[nodiscard]] std::uint16_t port() const { return port_; }

 private:
  UdpLineReader() = default;
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::unique_ptr<char[]> buf_;
  std::size_t cap_ = 0, begin_ = 0, end_ = 0;
  sockaddr_in peer_{};
  bool has_peer_ = false;
};

}  // namespace zm
