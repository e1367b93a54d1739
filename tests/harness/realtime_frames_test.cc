// Real-time frames (harness/realtime_frames.h): the profile's rate taken from the recording,
// arrivals on the (compressed) clock, the frames that arrived during an overrun dropped and the
// latest processed. A fake clock: nothing sleeps.
#include "harness/realtime_frames.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

namespace zm {
namespace {

// Frames stamped 0, 0.5, 1.0, ... (a 2 Hz recording).
class FakeSource final : public FrameSource {
 public:
  explicit FakeSource(int n) : n_(n) {}
  Result<bool> Next(Frame* f) override {
    if (i_ >= n_) return false;
    f->index = static_cast<std::uint64_t>(i_);
    f->stamp_s = 0.5 * i_;
    ++i_;
    return true;
  }
  std::uint32_t max_features() const override { return 4; }

 private:
  int n_;
  int i_ = 0;
};

double g_now = 0.0;
double FakeNow() { return g_now; }

TEST_CASE(
    "real-time frames: the profile's rate, overruns drop what arrived, the latest is processed") {
  FakeSource inner(20);  // 10 s of a 2 Hz recording
  g_now = 100.0;
  auto rt = RealtimeFrameSource::Create(
      inner,
      {.rate_hz = 1.0, .time_compression = 1.0, .origin_mono_s = 100.0, .now_mono_s = &FakeNow});
  REQUIRE(rt.ok());
  RealtimeFrameSource& s = **rt;
  Frame f;
  f.Reserve(4);

  CHECK(*s.NextArrival() == doctest::Approx(100.0));
  CHECK(s.FrameWaiting());
  REQUIRE(*s.Next(&f));
  CHECK(f.stamp_s == 0.0);
  // The next frame the 1 Hz rate takes is stamped 1.0 (0.5 is never taken).
  CHECK(*s.NextArrival() == doctest::Approx(101.0));
  CHECK_FALSE(s.FrameWaiting());
  g_now = 101.0;
  CHECK(s.FrameWaiting());
  REQUIRE(*s.Next(&f));
  CHECK(f.stamp_s == 1.0);
  CHECK(s.frames_dropped() == 0);

  // A tick overruns by 2.6 s: frames 2.0 and 3.0 arrived meanwhile, 3.0 wins, 2.0 is dropped.
  g_now = 103.6;
  REQUIRE(*s.Next(&f));
  CHECK(f.stamp_s == 3.0);
  CHECK(s.frames_dropped() == 1);
  CHECK(s.frames_processed() == 3);
  CHECK(s.frames_arrived() == 4);
  CHECK(*s.NextArrival() == doctest::Approx(104.0));

  // On time from here on: nothing more dropped; every taken frame arrives once.
  for (double t = 104.0; t <= 109.0; t += 1.0) {
    g_now = t;
    REQUIRE(*s.Next(&f));
    CHECK(f.stamp_s == doctest::Approx(t - 100.0));
  }
  CHECK_FALSE(*s.Next(&f));
  CHECK(s.frames_dropped() == 1);
  CHECK(s.frames_arrived() == 10);  // the 1 Hz grid over 10 s
  CHECK(s.frames_not_taken() == 10);
  CHECK(std::isinf(*s.NextArrival()));
}

TEST_CASE("real-time frames: time compression shrinks the clock, bad options are refused") {
  FakeSource inner(20);
  g_now = 0.0;
  auto rt = RealtimeFrameSource::Create(
      inner,
      {.rate_hz = 1.0, .time_compression = 4.0, .origin_mono_s = 0.0, .now_mono_s = &FakeNow});
  REQUIRE(rt.ok());
  Frame f;
  f.Reserve(4);
  REQUIRE(*(*rt)->Next(&f));
  CHECK(*(*rt)->NextArrival() == doctest::Approx(0.25));  // stamp 1.0 at 4x
  g_now = 1.0;  // 1 s of wall = 4 s of frames: 1, 2, 3 and 4 arrived; 4 is processed
  REQUIRE(*(*rt)->Next(&f));
  CHECK(f.stamp_s == 4.0);
  CHECK((*rt)->frames_dropped() == 3);

  FakeSource other(2);
  CHECK(RealtimeFrameSource::Create(other, {.rate_hz = 0.0}).status().code() ==
        StatusCode::kInvalidArgument);
  auto bad = RealtimeFrameSource::Create(other, {.rate_hz = 1.0, .time_compression = 0.0});
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("--time-compression") != std::string::npos);
}

}  // namespace
}  // namespace zm
