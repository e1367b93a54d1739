// Where the tick loop's frames come from (a seam: the loop sees only this interface).
//   ReplayFrameSource  the frames file of a recorded run (deterministic replay; OpenReplaySource)
//   StagedFrameSource  one frame at a time, handed in by zonemapd's session (daemon.h) after it
//                      read a protocol line and the input gate let the frame through: the live
//                      line protocol reaches the loop this way, with its control lines (route,
//                      budget) applied between ticks by the session.
// Every source fills a Frame reserved for max_features without allocating.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "common/param.h"
#include "common/status.h"
#include "localization/frame.h"

namespace zm {

// The largest live frame a loop accepts, declared once: zonemapd --max-features
// (DaemonOptions::max_features) and the public API's MapLoopOptions::max_features (checked equal
// at compile time in api/map_loop.cc) take it from here. Every source reserves its Frame for it.
inline constexpr Param<std::uint32_t> kMaxFeaturesParam{
    "max-features", 2048, 1, 65536, "the largest frame accepted on live input (features)"};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // true: `frame` holds the next frame; false: end of input. Errors are I/O or corrupt files.
  [[nodiscard]] virtual Result<bool> Next(Frame* frame) = 0;
  // Input lines refused before they became frames (live sources); summary.json's
  // malformed_lines.
  [[nodiscard]] virtual std::uint64_t malformed_lines() const { return 0; }
  [[nodiscard]] virtual std::uint32_t max_features() const = 0;
  // Camera frames (issue 26): the largest encoded colour image and the images' size (the map
  // camera's field of view at that resolution); all zero for a source whose frames carry their
  // features. The loop reserves its frame and builds its front-end from this.
  struct Images {
    std::uint32_t max_colour_bytes = 0;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
  };
  [[nodiscard]] virtual Images images() const { return {}; }
  // True when input is already waiting, so the driver's next read would not block: the loop's
  // idle part stops loading then (TickLoop::Idle). Never blocks. A recorded replay has no
  // arrival times: false.
  [[nodiscard]] virtual bool FrameWaiting() { return false; }
};

// Whoever reads the live input for a StagedFrameSource and can tell whether more is waiting
// (zonemapd's session: its line readers).
class InputProbe {
 public:
  virtual ~InputProbe() = default;
  [[nodiscard]] virtual bool Waiting() = 0;
};

[[nodiscard]] Result<std::unique_ptr<FrameSource>> OpenReplaySource(const std::string& frames_path);

class StagedFrameSource final : public FrameSource {
 public:
  explicit StagedFrameSource(std::uint32_t max_features) : max_features_(max_features) {
    staged_.Reserve(max_features);
  }
  // Camera frames will be staged (zonemapd's `image` lines, --tum, a frames file with images):
  // the loop builds its front-end from this. Before the loop is created; reserves the staged
  // frame for them (`feature_capacity`: what the front-end writes, at least max_features).
  void ExpectImages(const Images& images, std::uint32_t feature_capacity) {
    images_ = images;
    staged_.Reserve(feature_capacity, images.max_colour_bytes);
  }
  [[nodiscard]] Images images() const override { return images_; }
  // The frame to fill (reserved for max_features); Stage() hands it to the next Next().
  [[nodiscard]] Frame& staging() { return staged_; }
  void Stage() { ready_ = true; }
  // Swaps the staged frame into *frame (both keep their reserved buffers: no allocation).
  // false when nothing is staged.
  Result<bool> Next(Frame* frame) override;
  [[nodiscard]] std::uint64_t malformed_lines() const override { return malformed_; }
  [[nodiscard]] std::uint32_t max_features() const override { return max_features_; }
  void set_malformed_lines(std::uint64_t n) { malformed_ = n; }
  // Input waiting = a staged frame not yet taken, or the probe's input (null: none).
  void set_probe(InputProbe* probe) { probe_ = probe; }
  bool FrameWaiting() override { return ready_ || (probe_ != nullptr && probe_->Waiting()); }

 private:
  std::uint32_t max_features_;
  Images images_{};
  InputProbe* probe_ = nullptr;
  Frame staged_;
  bool ready_ = false;
  std::uint64_t malformed_ = 0;
  std::uint64_t next_index_ = 0;
};

}  // namespace zm
