#include "runtime/telemetry.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace zm {
namespace {
constexpr std::size_t kStdioBufferBytes = 1 << 16;
}

const char* TickStepName(TickStep step) {
  switch (step) {
    case TickStep::kReadFrame: return "read";
    case TickStep::kPoseUpdate: return "pose";
    case TickStep::kZoneLookup: return "zone";
    case TickStep::kPlan: return "plan";
    case TickStep::kApply: return "apply";
    case TickStep::kLocalize: return "localize";
    case TickStep::kRecord: return "record";
    case TickStep::kCount: break;
  }
  return "?";
}

TelemetryWriter::~TelemetryWriter() { Close(); }

Status TelemetryWriter::Open(const std::string& path) {
  Close();
  file_ = std::fopen(path.c_str(), "w");
  if (file_ == nullptr) {
    return IoError("cannot open telemetry file '" + path + "': " + std::strerror(errno));
  }
  stdio_buffer_ = static_cast<char*>(std::malloc(kStdioBufferBytes));
  if (stdio_buffer_ != nullptr) std::setvbuf(file_, stdio_buffer_, _IOFBF, kStdioBufferBytes);
  lines_ = 0;
  return Status::Ok();
}

bool TelemetryWriter::Write(const TickRecord& r, std::string_view extra) {
  if (file_ == nullptr) return false;
  int n = std::snprintf(
      line_, sizeof line_,
      "{\"tick\":%llu,\"stamp\":%.6f,\"x\":%.4f,\"y\":%.4f,\"yaw\":%.5f,\"zone\":%d,"
      "\"resident_keyframes\":%u,\"resident_bytes\":%llu,\"loaded\":%u,\"unloaded\":%u,"
      "\"db_transactions\":%u,\"db_queries\":%u,\"db_bytes_read\":%llu,\"load_ms\":%.4f,"
      "\"unload_ms\":%.4f,\"pending\":%u,\"idle_load_ms\":%.4f,\"idle_loaded\":%u,"
      "\"late_ms\":%.4f,\"over_budget\":%s,\"refused\":%llu,\"loop_closure\":%s,"
      "\"matched\":%lld,\"inliers\":%u,\"highest\":%lld,\"candidates\":%u,"
      "\"startup\":%s,\"stalled\":%s,\"tick_ms\":%.4f,\"steps_ms\":{",
      static_cast<unsigned long long>(r.tick), r.stamp_s, r.x_m, r.y_m, r.yaw_rad, r.zone.value,
      r.resident_keyframes, static_cast<unsigned long long>(r.resident_bytes), r.keyframes_loaded,
      r.keyframes_unloaded, r.db_transactions, r.db_queries,
      static_cast<unsigned long long>(r.db_bytes_read), r.load_ms, r.unload_ms,
      r.pending_keyframes, r.idle_load_ms, r.idle_keyframes_loaded, r.late_ms,
      r.over_budget ? "true" : "false", static_cast<unsigned long long>(r.refused_acquisitions),
      r.loop_closure ? "true" : "false", static_cast<long long>(r.matched_keyframe), r.inliers,
      static_cast<long long>(r.highest_hypothesis), r.candidates, r.startup ? "true" : "false",
      r.stalled ? "true" : "false", r.tick_ms);
  if (n < 0 || static_cast<std::size_t>(n) >= sizeof line_) return false;
  std::size_t used = static_cast<std::size_t>(n);
  for (int s = 0; s < kTickStepCount; ++s) {
    n = std::snprintf(line_ + used, sizeof line_ - used, "%s\"%s\":%.4f", s == 0 ? "" : ",",
                      TickStepName(static_cast<TickStep>(s)), r.step_ms[s]);
    if (n < 0 || static_cast<std::size_t>(n) >= sizeof line_ - used) return false;
    used += static_cast<std::size_t>(n);
  }
  if (used + 1 > sizeof line_) return false;
  line_[used++] = '}';
  // Database work beyond the loads' (issue 17 §5): blob reads, the searching part, and on the
  // start-up tick the part that was the start-up load.
  n = std::snprintf(line_ + used, sizeof line_ - used,
                    ",\"db_blob_reads\":%u,\"search_queries\":%u,\"search_transactions\":%u",
                    r.db_blob_reads, r.search_queries, r.search_transactions);
  if (n < 0 || static_cast<std::size_t>(n) >= sizeof line_ - used) return false;
  used += static_cast<std::size_t>(n);
  if (r.startup) {
    n = std::snprintf(line_ + used, sizeof line_ - used,
                      ",\"startup_db\":{\"queries\":%u,\"transactions\":%u,\"blob_reads\":%u}",
                      r.startup_db_queries, r.startup_db_transactions, r.startup_db_blob_reads);
    if (n < 0 || static_cast<std::size_t>(n) >= sizeof line_ - used) return false;
    used += static_cast<std::size_t>(n);
  }
  if (!extra.empty()) {
    if (used + 1 + extra.size() > sizeof line_) return false;
    line_[used++] = ',';
    std::memcpy(line_ + used, extra.data(), extra.size());
    used += extra.size();
  }
  if (used + 2 > sizeof line_) return false;
  line_[used++] = '}';
  line_[used++] = '\n';
  if (std::fwrite(line_, 1, used, file_) != used) return false;
  ++lines_;
  return true;
}

void TelemetryWriter::Flush() {
  if (file_ != nullptr) std::fflush(file_);
}

void TelemetryWriter::Close() {
  if (file_ != nullptr) {
    std::fclose(file_);
    file_ = nullptr;
  }
  std::free(stdio_buffer_);
  stdio_buffer_ = nullptr;
}

}  // namespace zm
