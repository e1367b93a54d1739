// Real-time frames for a replay (issue 17 §4): the recorded frames arrive on a clock, as a camera
// delivers them to RTAB-Map, instead of being handed to the loop as fast as it can take them.
//
//   - The loop takes frames at the profile's rate ([loop] rate_hz, RTAB-Map's detection rate,
//     1 Hz): of the recording (the simulator's 2 Hz), the first frame at or after each period
//     of the rate's grid arrives; the others are frames the rate limiter never takes (counted
//     apart, `frames_not_taken`).
//   - Frame k arrives at origin + (stamp_k - stamp_0) / time_compression on CLOCK_MONOTONIC
//     (the co-tenant's event lines use the same clock). The compression must be the same for
//     every run that is compared, and every report states it.
//   - When a tick overruns, the frames that arrived meanwhile are dropped and the latest one is
//     processed, as RTAB-Map does (its input queue holds one image): `frames_dropped`.
//   - Next() never sleeps (the wait is not the tick's time): the driver calls WaitForFrame()
//     first, and FrameWaiting() tells the loop's idle part that a frame is already there.
//
// Invariants: frames_arrived() = frames processed + frames_dropped(); no allocation after
// construction (the frames are reserved for the inner source's max_features and swapped).
#pragma once

#include <cstdint>
#include <limits>

#include "common/status.h"
#include "localization/frame.h"
#include "runtime/frame_source.h"

namespace zm {

struct RealtimeFrameOptions {
  double rate_hz = 1.0;              // frames taken per second of the recording's clock; > 0
  double time_compression = 1.0;     // > 0: frames-clock seconds per wall second (1 = real time)
  double origin_mono_s = 0.0;        // CLOCK_MONOTONIC at which the first frame arrives
  double (*now_mono_s)() = nullptr;  // the clock (tests inject one); null = MonotonicSeconds
};

class RealtimeFrameSource final : public FrameSource {
 public:
  // `inner` outlives this object. Errors: rate or compression not > 0.
  [[nodiscard]] static Result<std::unique_ptr<RealtimeFrameSource>> Create(
      FrameSource& inner, const RealtimeFrameOptions& options);

  // The latest frame that has arrived by now (dropping older ones that arrived too); if none has
  // arrived yet, the next one regardless (call WaitForFrame() first). false at the end.
  Result<bool> Next(Frame* frame) override;
  [[nodiscard]] std::uint32_t max_features() const override { return inner_.max_features(); }
  [[nodiscard]] Images images() const override { return inner_.images(); }
  [[nodiscard]] std::uint64_t malformed_lines() const override { return inner_.malformed_lines(); }
  // The next frame has arrived (never blocks).
  bool FrameWaiting() override;

  // Arrival time (monotonic s) of the next frame; +infinity when the input has ended.
  [[nodiscard]] Result<double> NextArrival();
  // Sleeps until the next frame has arrived (or returns at once at the end of the input).
  [[nodiscard]] Status WaitForFrame();

  [[nodiscard]] std::uint64_t frames_arrived() const noexcept { return processed_ + dropped_; }
  [[nodiscard]] std::uint64_t frames_dropped() const noexcept { return dropped_; }
  [[nodiscard]] std::uint64_t frames_processed() const noexcept { return processed_; }
  [[nodiscard]] std::uint64_t frames_not_taken() const noexcept { return not_taken_; }
  [[nodiscard]] double now_mono_s() const { return now_(); }
  // The clock's origin, when it is known only after the loop was built (before the first frame).
  void set_origin_mono_s(double origin) noexcept { options_.origin_mono_s = origin; }
  [[nodiscard]] const RealtimeFrameOptions& options() const noexcept { return options_; }

 private:
  RealtimeFrameSource(FrameSource& inner, const RealtimeFrameOptions& options);
  // Reads the next frame the rate takes into *f (skipping the others). false at the end.
  Result<bool> ReadTaken(Frame* f);
  Status FillAhead();
  [[nodiscard]] double Arrival(double stamp_s) const noexcept;

  FrameSource& inner_;
  RealtimeFrameOptions options_;
  double (*now_)();
  double period_s_ = 1.0;
  Frame ahead_;  // the next frame to process (valid when have_ahead_)
  Frame spare_;
  bool have_ahead_ = false;
  bool ended_ = false;
  bool have_stamp0_ = false;
  double stamp0_ = 0.0;
  std::uint64_t next_slot_ = 0;  // the rate grid's next period index
  std::uint64_t processed_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t not_taken_ = 0;
};

}  // namespace zm
