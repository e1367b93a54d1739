#include "harness/realtime_frames.h"

#include <cmath>
#include <ctime>
#include <utility>

#include "harness/cotenant.h"

namespace zm {

Result<std::unique_ptr<RealtimeFrameSource>> RealtimeFrameSource::Create(
    FrameSource& inner, const RealtimeFrameOptions& options) {
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz)) {
    return InvalidArgument("real-time frames: rate " + std::to_string(options.rate_hz) +
                           " Hz must be > 0");
  }
  if (!(options.time_compression > 0.0) || !std::isfinite(options.time_compression)) {
    return InvalidArgument("--time-compression " + std::to_string(options.time_compression) +
                           " must be > 0 (0 = no real-time frames)");
  }
  return std::unique_ptr<RealtimeFrameSource>(new RealtimeFrameSource(inner, options));
}

RealtimeFrameSource::RealtimeFrameSource(FrameSource& inner, const RealtimeFrameOptions& options)
    : inner_(inner),
      options_(options),
      now_(options.now_mono_s != nullptr ? options.now_mono_s : &MonotonicSeconds),
      period_s_(1.0 / options.rate_hz) {
  ahead_.Reserve(inner.max_features(), inner.images().max_colour_bytes);
  spare_.Reserve(inner.max_features(), inner.images().max_colour_bytes);
}

double RealtimeFrameSource::Arrival(double stamp_s) const noexcept {
  return options_.origin_mono_s + (stamp_s - stamp0_) / options_.time_compression;
}

Result<bool> RealtimeFrameSource::ReadTaken(Frame* f) {
  for (;;) {
    ZM_ASSIGN_OR_RETURN(bool more, inner_.Next(f));
    if (!more) return false;
    if (!have_stamp0_) {
      have_stamp0_ = true;
      stamp0_ = f->stamp_s;
    }
    // The rate's grid: period k starts at stamp0 + k / rate; the first frame at or after it is
    // taken (a microsecond of slack for stamps written in decimal).
    const double rel = (f->stamp_s - stamp0_) / period_s_ + 1e-6;
    if (rel < static_cast<double>(next_slot_)) {
      ++not_taken_;
      continue;
    }
    next_slot_ = static_cast<std::uint64_t>(std::floor(rel)) + 1;
    return true;
  }
}

Status RealtimeFrameSource::FillAhead() {
  if (have_ahead_ || ended_) return Status::Ok();
  ZM_ASSIGN_OR_RETURN(bool more, ReadTaken(&ahead_));
  have_ahead_ = more;
  ended_ = !more;
  return Status::Ok();
}

Result<double> RealtimeFrameSource::NextArrival() {
  ZM_RETURN_IF_ERROR(FillAhead());
  if (!have_ahead_) return std::numeric_limits<double>::infinity();
  return Arrival(ahead_.stamp_s);
}

Status RealtimeFrameSource::WaitForFrame() {
  ZM_ASSIGN_OR_RETURN(double at, NextArrival());
  if (!std::isfinite(at)) return Status::Ok();
  const double now = now_();
  if (now >= at || options_.now_mono_s != nullptr) return Status::Ok();  // a test's clock
  const double d = at - now;
  timespec ts{static_cast<time_t>(d), static_cast<long>((d - std::floor(d)) * 1e9)};
  // EINTR (a stop signal) returns early: the driver checks its flag and FrameWaiting() again.
  (void)nanosleep(&ts, nullptr);
  return Status::Ok();
}

bool RealtimeFrameSource::FrameWaiting() {
  if (!FillAhead().ok()) return true;  // let the loop read it and meet the error
  return have_ahead_ && Arrival(ahead_.stamp_s) <= now_();
}

Result<bool> RealtimeFrameSource::Next(Frame* frame) {
  ZM_RETURN_IF_ERROR(FillAhead());
  if (!have_ahead_) return false;
  const double now = now_();
  // Every frame that arrived while the last tick ran is overtaken by the latest one.
  bool have_spare = false;
  for (;;) {
    ZM_ASSIGN_OR_RETURN(bool more, ReadTaken(&spare_));
    if (!more) {
      ended_ = true;
      break;
    }
    if (Arrival(spare_.stamp_s) <= now) {
      ++dropped_;
      std::swap(ahead_, spare_);
      continue;
    }
    have_spare = true;
    break;
  }
  std::swap(*frame, ahead_);
  ++processed_;
  if (have_spare) {
    std::swap(ahead_, spare_);
    have_ahead_ = true;
  } else {
    have_ahead_ = false;
  }
  return true;
}

}  // namespace zm
