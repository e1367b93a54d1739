// One tick, published to its consumers (see tick_publisher.h).
#include "runtime/tick_publisher.h"

#include "runtime/text_line.h"

namespace zm {

Status TickPublisher::Open(const PublishOptions& options) {
  Close();
  options_ = options;
  tracker_ = PoseTracker(options.output);
  has_telemetry_ = !options.telemetry_path.empty();
  has_estimate_ = !options.estimate_path.empty();
  if (has_telemetry_) ZM_RETURN_IF_ERROR(telemetry_.Open(options.telemetry_path));
  if (has_estimate_) ZM_RETURN_IF_ERROR(estimate_.Open(options.estimate_path));
  return Status::Ok();
}

std::string_view TickPublisher::Publish(const TickRecord& r, std::string_view extra) {
  std::string_view line;
  if (options_.track_status) {
    tracker_.Update(r);
    const std::size_t n = FormatPoseLine(PoseLineOf(r, tracker_), pose_line_, sizeof pose_line_);
    line = {pose_line_, n};
  }
  if (has_estimate_) (void)estimate_.Write(r.stamp_s, r.pose);
  if (has_telemetry_) {
    std::string_view members = extra;
    if (options_.track_status) {
      TextLine t(extra_, sizeof extra_);
      t.Str("\"status\":\"").Str(LocalizationStatusName(tracker_.status()));
      t.Str("\",\"frames_since_fix\":").U64(tracker_.frames_since_fix());
      t.Str(",\"sigma_xy_m\":").General(tracker_.sigma_xy_m(), 6);
      t.Str(",\"k_max\":").U64(r.k_max).Str(",\"malformed\":").U64(r.malformed_lines);
      if (!extra.empty()) t.Char(',').Str(extra);
      members = t.ok() ? t.view() : std::string_view();
    }
    (void)telemetry_.Write(r, members);
  }
  const std::uint32_t every = options_.flush_ticks;
  if (every != 0 && (r.tick + 1) % every == 0) Flush();
  return line;
}

void TickPublisher::Flush() {
  if (has_estimate_) estimate_.Flush();  // first: a tick on disk always has its pose on disk
  if (has_telemetry_) telemetry_.Flush();
}

void TickPublisher::Close() {
  if (has_estimate_) estimate_.Close();
  if (has_telemetry_) telemetry_.Close();
  has_estimate_ = false;
  has_telemetry_ = false;
}

}  // namespace zm
