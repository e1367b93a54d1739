#include "runtime/telemetry.h"

#include "runtime/text_line.h"

namespace zm {
namespace {

// `,"key":{"name":ms,...}`: n times in ms, the i-th named name(i).
template <typename Name>
void Times(TextLine& t, std::string_view key, const double* ms, int n, Name name) {
  t.Str(",\"").Str(key).Str("\":{");
  for (int i = 0; i < n; ++i) {
    if (i != 0) t.Char(',');
    t.Char('"').Str(name(i)).Str("\":").Fixed(ms[i], 4);
  }
  t.Char('}');
}

}  // namespace

const char* LoopStageName(LoopStage stage) {
  switch (stage) {
    case LoopStage::kFeatures: return "features";
    case LoopStage::kQuantize: return "quantize";
    case LoopStage::kLikelihood: return "likelihood";
    case LoopStage::kVerify: return "verify";
    case LoopStage::kMemory: return "memory";
  }
  return "?";
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

Status TelemetryWriter::Open(const std::string& path) {
  lines_ = 0;
  return file_.Open(path, "telemetry file");
}

bool TelemetryWriter::Write(const TickRecord& r, std::string_view extra) {
  if (!file_.is_open()) return false;
  // std::to_chars through TextLine, not snprintf: glibc's printf takes a slow path that mallocs
  // its spec table once a format has more than a handful of conversions (this line has about 30), and
  // the C locale could turn "1.5" into "1,5".
  const auto b = [](bool v) { return v ? "true" : "false"; };
  TextLine t(line_, sizeof line_);
  t.Str("{\"tick\":").U64(r.tick).Str(",\"stamp\":").Fixed(r.stamp_s, 6);
  t.Str(",\"x\":").Fixed(r.x_m, 4).Str(",\"y\":").Fixed(r.y_m, 4);
  t.Str(",\"yaw\":").Fixed(r.yaw_rad, 5).Str(",\"zone\":").I64(r.zone.value);
  t.Str(",\"resident_keyframes\":").U64(r.resident_keyframes);
  t.Str(",\"resident_bytes\":").U64(r.resident_bytes);
  t.Str(",\"loaded\":").U64(r.keyframes_loaded).Str(",\"unloaded\":").U64(r.keyframes_unloaded);
  t.Str(",\"db_transactions\":").U64(r.db_transactions).Str(",\"db_queries\":").U64(r.db_queries);
  t.Str(",\"db_bytes_read\":").U64(r.db_bytes_read);
  t.Str(",\"load_ms\":").Fixed(r.load_ms, 4).Str(",\"unload_ms\":").Fixed(r.unload_ms, 4);
  t.Str(",\"pending\":").U64(r.pending_keyframes);
  t.Str(",\"idle_load_ms\":").Fixed(r.idle_load_ms, 4);
  t.Str(",\"idle_loaded\":").U64(r.idle_keyframes_loaded);
  t.Str(",\"late_ms\":").Fixed(r.late_ms, 4);
  t.Str(",\"over_budget\":").Str(b(r.over_budget));
  t.Str(",\"refused\":").U64(r.refused_acquisitions);
  t.Str(",\"loop_closure\":").Str(b(r.loop_closure));
  t.Str(",\"matched\":").I64(r.matched_keyframe).Str(",\"inliers\":").U64(r.inliers);
  t.Str(",\"highest\":").I64(r.highest_hypothesis).Str(",\"candidates\":").U64(r.candidates);
  t.Str(",\"startup\":").Str(b(r.startup)).Str(",\"stalled\":").Str(b(r.stalled));
  t.Str(",\"tick_ms\":").Fixed(r.tick_ms, 4);
  Times(t, "steps_ms", r.step_ms, kTickStepCount,
        [](int i) { return TickStepName(static_cast<TickStep>(i)); });
  // Where the tick's time went as RTAB-Map reports it (LoopStage), and what localization had to
  // work with: the frame's features, its image's fate, the vocabulary's likelihood and work.
  Times(t, "stages_ms", r.stage_ms, kLoopStageCount,
        [](int i) { return LoopStageName(static_cast<LoopStage>(i)); });
  t.Str(",\"features\":").U64(r.features);
  if (r.has_image) t.Str(",\"image_refused\":").Str(b(r.image_refused));
  if (r.vocabulary) {
    t.Str(",\"likelihood\":").Fixed(r.likelihood, 5);
    t.Str(",\"postings_walked\":").U64(r.postings_walked);
  }
  // Database work beyond the loads' (issue 17 §5): blob reads, the searching part, and on the
  // start-up tick the part that was the start-up load.
  t.Str(",\"db_blob_reads\":").U64(r.db_blob_reads);
  t.Str(",\"search_queries\":").U64(r.search_queries);
  t.Str(",\"search_transactions\":").U64(r.search_transactions);
  if (r.startup) {
    t.Str(",\"startup_db\":{\"queries\":").U64(r.startup_db_queries);
    t.Str(",\"transactions\":").U64(r.startup_db_transactions);
    t.Str(",\"blob_reads\":").U64(r.startup_db_blob_reads).Char('}');
  }
  if (!extra.empty()) t.Char(',').Str(extra);
  t.Str("}\n");
  if (!t.ok()) return false;
  if (!file_.Write(t.view())) return false;
  ++lines_;
  return true;
}

void TelemetryWriter::Flush() { file_.Flush(); }
void TelemetryWriter::Close() { file_.Close(); }

}  // namespace zm
