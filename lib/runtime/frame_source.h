// Where the tick loop's frames come from (a seam: the loop sees only this interface).
//   ReplayFrameSource  the frames file of a simulated localization run (deterministic replay)
//   LineFrameSource    the live line protocol (line_protocol.h) on a file descriptor (stdin)
//   UdpFrameSource     the same protocol, one datagram per line, on a loopback UDP port
// Every source fills a Frame reserved for max_features without allocating; live sources count
// malformed lines and skip them.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "common/status.h"
#include "localization/frame.h"
#include "runtime/line_protocol.h"

namespace zm {

class FrameReader;

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // true: `frame` holds the next frame; false: end of input. Errors are I/O or corrupt files.
  [[nodiscard]] virtual Result<bool> Next(Frame* frame) = 0;
  [[nodiscard]] virtual std::uint64_t malformed_lines() const { return 0; }
  [[nodiscard]] virtual std::uint32_t max_features() const = 0;
  // True when input is already waiting, so Next() would not block: the loop's idle part stops
  // loading then (TickLoop::Idle). Never blocks. A recorded replay has no arrival times: false.
  [[nodiscard]] virtual bool FrameWaiting() { return false; }
};

[[nodiscard]] Result<std::unique_ptr<FrameSource>> OpenReplaySource(const std::string& frames_path);

class LineFrameSource final : public FrameSource {
 public:
  // Reads lines from `fd` (not owned). Lines longer than the buffer are malformed.
  LineFrameSource(int fd, std::uint32_t max_features);
  Result<bool> Next(Frame* frame) override;
  [[nodiscard]] std::uint64_t malformed_lines() const override { return malformed_; }
  [[nodiscard]] std::uint32_t max_features() const override { return max_features_; }
  bool FrameWaiting() override;
  [[nodiscard]] const LineError& last_error() const { return last_error_; }

 private:
  int fd_;
  std::uint32_t max_features_;
  std::unique_ptr<char[]> buf_;  // allocated once in the constructor
  std::size_t cap_ = 0, begin_ = 0, end_ = 0;
  bool eof_ = false;
  bool skipping_long_line_ = false;
  std::uint64_t malformed_ = 0;
  std::uint64_t next_index_ = 0;
  LineError last_error_;
};

class UdpFrameSource final : public FrameSource {
 public:
  // Binds 127.0.0.1:port (loopback only). An empty datagram ends the stream.
  [[nodiscard]] static Result<std::unique_ptr<UdpFrameSource>> Bind(std::uint16_t port,
                                                                    std::uint32_t max_features);
  ~UdpFrameSource() override;
  Result<bool> Next(Frame* frame) override;
  [[nodiscard]] std::uint64_t malformed_lines() const override { return malformed_; }
  [[nodiscard]] std::uint32_t max_features() const override { return max_features_; }
  bool FrameWaiting() override;
  [[nodiscard]] std::uint16_t port() const { return port_; }

 private:
  UdpFrameSource() = default;
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::uint32_t max_features_ = 0;
  std::unique_ptr<char[]> buf_;
  std::size_t cap_ = 0;
  std::uint64_t malformed_ = 0;
  std::uint64_t next_index_ = 0;
};

}  // namespace zm
