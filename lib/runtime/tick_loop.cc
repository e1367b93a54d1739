// The tick loop. See tick_loop.h for the step order and the allocation contract.
#include "runtime/tick_loop.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "common/elapsed.h"
#include "localization/map_vocabulary.h"
#include "runtime/map_setup.h"

namespace zm {

using Clock = std::chrono::steady_clock;

TickLoop::TickLoop(const LoopConfig& config, FrameSource& frames, Arena arena, MapIndex index)
    : config_(config), frames_(frames), arena_(std::move(arena)), map_index_(std::move(index)) {}

TickLoop::~TickLoop() = default;

Result<std::unique_ptr<TickLoop>> TickLoop::Create(const LoopConfig& config, MapReader& map,
                                                   FrameSource& frames,
                                                   LoopPlanInputs plan_inputs) {
  const MapMetadata& meta = map.metadata();
  if (meta.keyframe_count == 0) return InvalidArgument("the map database has no keyframes");
  if (!(config.loop.rate_hz > 0.0)) return InvalidArgument("loop rate_hz must be > 0");
  const LoadSliceOptions& lo = config.loads;
  if (!(lo.tick_ms >= 0.0) || !(lo.idle_ms >= 0.0) || !(lo.margin_ms >= 0.0)) {
    return InvalidArgument("loads: tick_ms, idle_ms and margin_ms must be >= 0");
  }

  // Metadata only: no payload is read to decide anything.
  ZM_ASSIGN_OR_RETURN(std::vector<KeyframeMeta> keyframes, map.Keyframes());
  ZM_ASSIGN_OR_RETURN(std::vector<LinkRecord> links, map.Links());
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneRecord> zone_records, map.Zones());
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneMember> members, map.ZoneMembers());
  if (zone_records.empty()) {
    return FailedPrecondition(
        "the map database has no zones: run `zonemap zones annotate DB ZONES.geojson` first");
  }
  ZM_ASSIGN_OR_RETURN(ZoneSet zone_set, ZoneSetFromRecords(zone_records, members));
  ZM_ASSIGN_OR_RETURN(MapIndex index, BuildPolicyIndex(keyframes, links, zone_set, members));

  // The map's vocabulary, when it has one: the localizer's likelihood over the resident set.
  // Read before the budget, which counts it (and the index over the arena's slots).
  ZM_ASSIGN_OR_RETURN(std::optional<Vocabulary> vocabulary, LoadMapVocabulary(map, "the map"));
  const FrameSource::Images images = frames.images();
  // The one derivation of K_max, the arena and localization's memory (budget.h).
  ZM_ASSIGN_OR_RETURN(
      const Budget budget,
      DeriveBudget(LoopBudgetInputs(config, meta, vocabulary ? &*vocabulary : nullptr, images)));

  // The bounded policies get an arena of exactly K_max slots: exceeding the budget is then
  // physically impossible. basic and unbounded model RTAB-Map's heap, which grows: their arena
  // holds the whole map and the over-budget flag measures by how much they exceed MemoryThr.
  // Only a bounded arena may be locked: its size is the budget; a heap that grows with the map
  // is ordinary memory, as RTAB-Map's is (map.lock_arena is then ignored; summary: arena_locked).
  auto arena_or = Arena::Create({.memory_thr_keyframes = budget.arena_slots,
                                 .budget_bytes = 0,
                                 .slot_bytes = budget.arena_slot_bytes,
                                 .lock = config.map.lock_arena && budget.bounded,
                                 .prefault = config.map.prefault_arena,
                                 .release_to_os = !budget.bounded});
  if (auto* err = std::get_if<ArenaError>(&arena_or)) return ResourceExhausted(err->message);

  std::unique_ptr<TickLoop> loop(
      new TickLoop(config, frames, std::move(std::get<Arena>(arena_or)), std::move(index)));
  loop->budget_ = budget;
  loop->zone_set_ = std::move(zone_set);
  loop->zone_index_ = ZoneIndex(loop->zone_set_, config.zones);
  loop->route_ = std::move(plan_inputs.route);

  // basic may start from the working memory the map database recorded (map_setup.h).
  RecordedWorkingMemory recorded;
  if (StartsFromLastWorkingMemory(config.policy)) {
    ZM_ASSIGN_OR_RETURN(recorded, map.LastWorkingMemory());
  }
  PolicyOptions popt = PolicyOptionsFor(config, budget, keyframes,
                                        std::move(plan_inputs.oracle_future), &recorded);
  // basic reads the long-term-memory nodes its graph searches admit from the map database.
  loop->ltm_graph_ = std::make_unique<SourceLtmGraph>(loop->map_index_, map);
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MemoryPolicy> policy,
                      MakePolicy(loop->map_index_, popt, loop->ltm_graph_.get()));
  loop->decide_ = std::make_unique<DecideStep>(
      loop->map_index_, std::move(policy),
      DecideOptions{.small_displacement_m = config.loop.small_displacement_m,
                    .small_displacement_rad = config.loop.small_displacement_rad},
      &loop->zone_index_, loop->route_);
  loop->working_set_ =
      std::make_unique<WorkingSet>(loop->map_index_, loop->arena_, map,
                                                     budget.k_max, config.loads.sliced);

  LocalizerConfig lc = config.localizer;
  lc.reserve_keyframes = std::max<std::uint32_t>(lc.reserve_keyframes, budget.arena_slots);
  lc.reserve_features = std::max<std::uint32_t>(lc.reserve_features, frames.max_features());
  if (images.max_colour_bytes > 0) {
    // Camera frames: the loop extracts their features itself, inside the tick, in the frame
    // scratch the budget counted.
    lc.reserve_features = std::max<std::uint32_t>(lc.reserve_features, config.orb.max_features);
    OrbOptions orb = config.orb;
    orb.scratch_bytes = budget.frame_scratch_bytes;
    ZM_ASSIGN_OR_RETURN(loop->front_end_,
                        FrontEnd::Create(orb, meta.camera, images.width, images.height));
  }
  ZM_RETURN_IF_ERROR(ValidateLocalizerConfig(lc, meta.camera));
  loop->localizer_ = std::make_unique<Localizer>(lc, meta.camera);
  loop->vocabulary_ = std::move(vocabulary);
  if (loop->vocabulary_.has_value()) {
    ZM_RETURN_IF_ERROR(loop->localizer_->UseVocabulary(&*loop->vocabulary_, budget.arena_slots));
  }
  // One derivation: what was reserved is what the budget counted (a mismatch is a bug here).
  const std::uint64_t scratch =
      loop->front_end_ ? loop->front_end_->extractor().scratch_stats().capacity_bytes : 0;
  if (loop->localizer_->index_memory_bytes() != budget.index_bytes ||
      scratch != budget.frame_scratch_bytes) {
    return Internal("the loop reserved an inverted index of " +
                    std::to_string(loop->localizer_->index_memory_bytes()) +
                    " bytes and a frame scratch of " + std::to_string(scratch) +
                    " bytes; the budget counted " + std::to_string(budget.index_bytes) + " and " +
                    std::to_string(budget.frame_scratch_bytes));
  }

  loop->frame_.Reserve(std::max<std::uint32_t>({frames.max_features(), config.orb.max_features, 1}),
                       images.max_colour_bytes);
  loop->resident_views_.reserve(budget.arena_slots);
  loop->frame_period_s_ = 1.0 / config.loop.rate_hz;
  // Keyframe body poses in MapIndex order (ascending id), for the localizer's heading gate.
  std::sort(keyframes.begin(), keyframes.end(),
            [](const KeyframeMeta& a, const KeyframeMeta& b) { return a.id < b.id; });
  loop->keyframe_poses_.reserve(keyframes.size());
  for (const KeyframeMeta& k : keyframes) loop->keyframe_poses_.push_back(k.pose);
  return loop;
}

BudgetInputs LoopBudgetInputs(const LoopConfig& config, const MapMetadata& map,
                              const Vocabulary* vocabulary, const FrameSource::Images& images) {
  BudgetInputs in = BudgetInputsFor(config.device, config.model, config.map, config.policy.kind,
                                    map.largest_payload_bytes, map.keyframe_count);
  LocalizationInputs& l = in.localization;
  if (vocabulary != nullptr) {
    l.vocabulary_bytes = vocabulary->memory_bytes();
    l.vocabulary_words = vocabulary->word_count();
    l.word_features = config.localizer.word_features;
  }
  if (images.max_colour_bytes > 0) {
    // The front-end's images: their declared size, else the map camera's (FrontEnd::Create).
    const bool sized = images.width != 0 && images.height != 0;
    l.image_width = sized ? images.width : map.camera.width;
    l.image_height = sized ? images.height : map.camera.height;
    l.scratch_bytes = config.orb.scratch_bytes;
  }
  return in;
}

DbWork SteadyDbWork(const LoopTotals& t) {
  return DbWork{t.db_queries - t.startup.db_queries, t.db_transactions - t.startup.db_transactions,
                t.db_blob_reads - t.startup.db_blob_reads, t.db_bytes_read - t.startup.bytes_read};
}

void TickLoop::NoteError(const Status& s) {
  ++totals_.step_errors;
  if (totals_.first_error.ok()) totals_.first_error = s;
  record_.stalled = true;
}

void TickLoop::Account(const TickTelemetry& t) {
  // The working set's counts a run sums: keyframes and zones moved, database work in one unit.
  using Count = std::pair<std::uint64_t LoopTotals::*, std::uint32_t TickTelemetry::*>;
  static constexpr Count kCounts[] = {
      {&LoopTotals::keyframes_loaded, &TickTelemetry::keyframes_loaded},
      {&LoopTotals::keyframes_unloaded, &TickTelemetry::keyframes_unloaded},
      {&LoopTotals::keyframes_cancelled, &TickTelemetry::keyframes_cancelled},
      {&LoopTotals::loads_preempted, &TickTelemetry::loads_preempted},
      {&LoopTotals::zone_loads, &TickTelemetry::zones_loaded},
      {&LoopTotals::db_transactions, &TickTelemetry::db_transactions},
      {&LoopTotals::db_queries, &TickTelemetry::db_queries},
      {&LoopTotals::db_blob_reads, &TickTelemetry::db_blob_reads},
      {&LoopTotals::search_queries, &TickTelemetry::search_queries},
      {&LoopTotals::search_transactions, &TickTelemetry::search_transactions},
  };
  for (const auto& [total, count] : kCounts) totals_.*total += t.*count;
  totals_.db_bytes_read += t.db_bytes_read;
  totals_.load_ms += t.load_ms;
  totals_.unload_ms += t.unload_ms;
  totals_.peak_resident_keyframes =
      std::max(totals_.peak_resident_keyframes, t.peak_resident_keyframes);
}

Result<bool> TickLoop::Tick() {
  if (config_.loop.max_ticks != 0 && totals_.ticks >= config_.loop.max_ticks) return false;
  const Clock::time_point t_tick = Clock::now();
  tick_start_ = t_tick;
  const bool startup = totals_.ticks == 0;

  // 1. Read a frame. (The previous tick's record stays readable until a frame arrives.)
  Clock::time_point t0 = Clock::now();
  auto next = frames_.Next(&frame_);
  if (!next.ok()) return next.status();
  if (!next.value()) return false;
  record_ = TickRecord{};
  tel_ = TickTelemetry{};
  record_.step_ms[static_cast<int>(TickStep::kReadFrame)] = MsSince(t0);
  // A camera frame: its features from its image, here in the tick (the features stage).
  if (frame_.has_image()) {
    FrontEndTimes fe;
    Status s = front_end_ != nullptr
                   ? front_end_->Process(&frame_, &fe)
                   : FailedPrecondition("frame " + std::to_string(frame_.index) +
                                        " has an image but the source declared none");
    record_.stage_ms[static_cast<int>(LoopStage::kFeatures)] = fe.decode_ms + fe.extract_ms;
    record_.has_image = true;
    if (!s.ok()) {
      // Refused: no features, so the localizer does nothing and the tick runs on odometry.
      record_.image_refused = true;
      ++totals_.images_refused;
      if (totals_.first_image_error.ok()) totals_.first_image_error = s;
      frame_error_ = std::move(s);
    }
  }
  record_.features = frame_.feature_count();
  // What the idle parts since the last tick did (Idle()).
  record_.idle_load_ms = std::exchange(idle_ms_, 0.0);
  record_.idle_keyframes_loaded = std::exchange(idle_keyframes_, 0U);
  record_.late_ms = std::exchange(late_ms_, 0.0);
  record_.stalled = std::exchange(idle_error_, false);
  const bool idle_over_budget = std::exchange(idle_over_budget_, false);

  // 2.-4. The decide step: the pose (odometry composed with the current correction), its zone
  //        (constant time, hysteresis, own floor only), the policy's plan: unload, then load
  //        (the start-up load on the first frame).
  const Pose3 correction = t_map_odom_;
  const Pose3 predicted = correction * frame_.odom;
  DecideStep::Times times;
  const Plan& plan = decide_->Before(frame_.stamp_s, predicted, kNoZone, &times);
  const ZoneId zone = decide_->zone();
  record_.step_ms[static_cast<int>(TickStep::kPoseUpdate)] = times.pose_ms;
  record_.step_ms[static_cast<int>(TickStep::kZoneLookup)] = times.zone_ms;
  record_.step_ms[static_cast<int>(TickStep::kPlan)] = times.plan_ms;

  // 5. Apply the plan: releases at once, loads queued (unsliced: loaded). Then the robot's own
  //    zone first: at start-up its load to the end (the start-up load); afterwards an in-tick
  //    slice of it, so the zone just entered starts loading now, not after the tick.
  t0 = Clock::now();
  if (!plan.empty()) {
    const Status s = working_set_->Apply(plan, &tel_);
    if (!s.ok()) NoteError(s);
  }
  if (working_set_->loading()) {
    working_set_->Prioritize(zone);
    LoadSlice slice;
    slice.zone = zone;  // the robot's zone (or a keyframe batch); kNoZone: whatever is first
    if (!startup) {
      const LoadSliceOptions& lo = config_.loads;
      slice.min_keyframes = 1;  // progress even when a tick has no time left
      if (lo.tick_ms > 0.0) {
        slice.deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                            std::chrono::duration<double, std::milli>(lo.tick_ms));
      }
      if (lo.tick_bytes > 0) slice.max_bytes = lo.tick_bytes;
    }
    const Status s = working_set_->StepLoads(slice, &tel_);
    if (!s.ok()) NoteError(s);
  }
  record_.step_ms[static_cast<int>(TickStep::kApply)] = MsSince(t0);
  if (startup) {
    totals_.startup.load_ms = tel_.load_ms;
    totals_.startup.keyframes_loaded = tel_.keyframes_loaded;
    totals_.startup.bytes_read = tel_.db_bytes_read;
    totals_.startup.db_transactions = tel_.db_transactions;
    totals_.startup.db_queries = tel_.db_queries;
    totals_.startup.db_blob_reads = tel_.db_blob_reads;
    record_.startup_db_queries = tel_.db_queries;
    record_.startup_db_transactions = tel_.db_transactions;
    record_.startup_db_blob_reads = tel_.db_blob_reads;
  }

  // 6. Localize on the resident set only, then the after-localization plan (basic).
  t0 = Clock::now();
  resident_views_.clear();
  for (const WorkingSet::Resident& r : working_set_->resident()) {
    auto view = DecodePayload(arena_.Slot(r.slot), {.verify_crc = false}, /*blob_is_slot=*/true);
    if (!view.ok()) continue;  // cannot happen for a slot the loader validated
    resident_views_.push_back({r.id, keyframe_poses_[r.index], view.value(), r.slot});
  }
  const LocalizeResult loc = localizer_->Localize(frame_, predicted, resident_views_);
  Pose3 estimate = predicted;
  if (loc.accepted) {
    t_map_odom_ = MapFromOdomCorrection(loc.t_map_cam, frame_.odom);  // used from next tick
    estimate = loc.t_map_body;
    ++totals_.frames_localized;
  }
  totals_.closures_accepted += loc.closures_accepted;
  totals_.closures_rejected += loc.closures_rejected;
  const Plan& after =
      decide_->After(loc.highest_hypothesis, loc.accepted ? loc.matched : KeyframeId{0});
  if (!after.empty()) {
    const Status s = working_set_->Apply(after, &tel_);
    if (!s.ok()) NoteError(s);
  }
  record_.step_ms[static_cast<int>(TickStep::kLocalize)] = MsSince(t0);
  double* stage = record_.stage_ms;
  stage[static_cast<int>(LoopStage::kQuantize)] = loc.quantize_ms;
  stage[static_cast<int>(LoopStage::kLikelihood)] = loc.likelihood_ms;
  stage[static_cast<int>(LoopStage::kVerify)] = loc.verify_ms;
  // Memory management: the plans, unloads and loads, and keeping the index equal to the
  // resident set (the after-localization plan is the localize step's remainder).
  stage[static_cast<int>(LoopStage::kMemory)] =
      record_.step_ms[static_cast<int>(TickStep::kPoseUpdate)] +
      record_.step_ms[static_cast<int>(TickStep::kZoneLookup)] +
      record_.step_ms[static_cast<int>(TickStep::kPlan)] +
      record_.step_ms[static_cast<int>(TickStep::kApply)] + loc.index_ms +
      std::max(0.0, record_.step_ms[static_cast<int>(TickStep::kLocalize)] - loc.index_ms -
                        loc.quantize_ms - loc.likelihood_ms - loc.verify_ms);
  record_.vocabulary = localizer_->has_vocabulary();
  record_.likelihood = loc.highest_likelihood;
  record_.postings_walked = loc.postings_walked;

  // 7. Record.
  t0 = Clock::now();
  Account(tel_);
  const std::uint32_t resident = working_set_->resident_count();
  const std::uint64_t resident_bytes = working_set_->resident_bytes();
  totals_.peak_resident_keyframes = std::max(totals_.peak_resident_keyframes, resident);
  totals_.peak_resident_bytes = std::max(totals_.peak_resident_bytes, resident_bytes);
  totals_.max_pending_keyframes =
      std::max(totals_.max_pending_keyframes, working_set_->pending_count());
  const std::uint32_t tick_peak = std::max(tel_.peak_resident_keyframes, resident);
  const bool over = idle_over_budget || tick_peak > budget_.k_max;
  if (over) {
    ++totals_.over_budget_ticks;
    totals_.max_over_budget_keyframes =
        std::max(totals_.max_over_budget_keyframes, tick_peak - budget_.k_max);
    totals_.longest_over_budget_run = std::max(totals_.longest_over_budget_run, ++over_budget_run_);
  } else {
    over_budget_run_ = 0;
  }
  if (record_.stalled) ++totals_.stalled_ticks;

  record_.tick = totals_.ticks;
  record_.stamp_s = frame_.stamp_s;
  record_.startup = startup;
  record_.pose = estimate;
  record_.correction = correction;
  record_.map_from_odom = t_map_odom_;
  record_.k_max = budget_.k_max;
  record_.malformed_lines = frames_.malformed_lines();
  record_.x_m = estimate.translation().x();
  record_.y_m = estimate.translation().y();
  record_.yaw_rad = Yaw(estimate);
  record_.zone = zone;
  record_.resident_keyframes = resident;
  record_.resident_bytes = resident_bytes;
  record_.keyframes_loaded = tel_.keyframes_loaded;
  record_.keyframes_unloaded = tel_.keyframes_unloaded;
  record_.db_transactions = tel_.db_transactions;
  record_.db_queries = tel_.db_queries;  // loads and searches, one unit
  record_.db_bytes_read = tel_.db_bytes_read;
  record_.db_blob_reads = tel_.db_blob_reads;
  record_.search_queries = tel_.search_queries;
  record_.search_transactions = tel_.search_transactions;
  record_.pending_keyframes = working_set_->pending_count();
  record_.load_ms = tel_.load_ms;
  record_.unload_ms = tel_.unload_ms;
  record_.over_budget = over;
  record_.refused_acquisitions = arena_.stats().refused;
  record_.loop_closure = loc.accepted;
  record_.matched_keyframe = loc.matched.value;
  record_.inliers = loc.inliers;
  record_.closure_covariance = loc.body_covariance;
  record_.reprojection_rms_px = loc.reprojection_rms_px;
  record_.highest_hypothesis = loc.highest_hypothesis.value;
  record_.candidates = loc.candidates_examined;
  record_.step_ms[static_cast<int>(TickStep::kRecord)] = MsSince(t0);
  // The frame's latency: its own steps plus any wait on the idle part before it (header).
  record_.tick_ms = MsSince(t_tick) + record_.late_ms;
  if (record_.late_ms > 0.0) {
    ++totals_.late_ticks;
    totals_.max_late_ms = std::max(totals_.max_late_ms, record_.late_ms);
  }
  if (startup) {
    totals_.startup.tick_ms = record_.tick_ms;
  } else {
    totals_.tick_ms.Add(record_.tick_ms);
    for (std::size_t i = 0; i < totals_.stage_ms.size(); ++i) {
      totals_.stage_ms[i].Add(record_.stage_ms[i]);
    }
    totals_.late_ms += record_.late_ms;
  }
  totals_.simulated_s += std::max(frame_period_s_, record_.tick_ms / 1000.0);
  ++totals_.ticks;
  return true;
}

TickLoop::IdleReport TickLoop::Idle(Clock::time_point frame_due) {
  IdleReport report;
  if (totals_.ticks == 0 || !working_set_->sliced() || !working_set_->loading()) return report;
  const Clock::time_point start = Clock::now();
  const LoadSliceOptions& lo = config_.loads;
  const auto ms = [](double v) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(v));
  };
  if (frame_due == Clock::time_point{}) {
    frame_due = tick_start_ + ms(frame_period_s_ * 1000.0);  // the frames' clock
  }
  LoadSlice slice;
  slice.deadline = frame_due - ms(lo.margin_ms);
  if (lo.idle_ms > 0.0) slice.deadline = std::min(slice.deadline, start + ms(lo.idle_ms));
  if (lo.idle_bytes > 0) slice.max_bytes = lo.idle_bytes;
  slice.interrupt = &frame_waiting_;
  if (slice.deadline <= start) {  // the next frame is (nearly) due: no idle time this tick
    report.pending_keyframes = working_set_->pending_count();
    return report;
  }
  TickTelemetry t;
  const Status s = working_set_->StepLoads(slice, &t);
  if (!s.ok()) {
    ++totals_.step_errors;
    if (totals_.first_error.ok()) totals_.first_error = s;
    idle_error_ = true;
  }
  const Clock::time_point end = Clock::now();
  report.ms = std::chrono::duration<double, std::milli>(end - start).count();
  report.keyframes_loaded = t.keyframes_loaded;
  report.bytes_read = t.db_bytes_read;
  report.pending_keyframes = working_set_->pending_count();
  // Only the idle part's own overrun: a tick that already ran past the due time left no idle.
  const Clock::time_point due = std::max(frame_due, start);
  report.late_ms = end > due ? std::chrono::duration<double, std::milli>(end - due).count() : 0.0;
  Account(t);
  totals_.peak_resident_bytes = std::max(totals_.peak_resident_bytes, working_set_->resident_bytes());
  totals_.idle_load_ms += report.ms;
  totals_.idle_keyframes_loaded += t.keyframes_loaded;
  idle_ms_ += report.ms;
  idle_keyframes_ += t.keyframes_loaded;
  late_ms_ += report.late_ms;
  idle_over_budget_ = idle_over_budget_ || t.over_budget;
  return report;
}

const char* BudgetOutcomeName(BudgetChange::Outcome outcome) {
  switch (outcome) {
    case BudgetChange::Outcome::kApplied: return "ok";
    case BudgetChange::Outcome::kClamped: return "clamped";
    case BudgetChange::Outcome::kIgnored: return "ignored";
    case BudgetChange::Outcome::kRefused: return "refused";
  }
  return "refused";
}

void TickLoop::ReserveRoute(std::size_t zones) {
  route_.reserve(zones);
  route_scratch_.reserve(std::max(zones, route_.capacity()));
  route_.reserve(route_scratch_.capacity());
  decide_->RebindRoute(route_);
}

bool TickLoop::SetRoute(std::span<const Eigen::Vector3d> waypoints) {
  route_scratch_.clear();
  const std::size_t capacity = route_scratch_.capacity();
  bool fits = true;
  const auto note = [&](const Eigen::Vector3d& p) {
    const ZoneId z = zone_index_.Lookup(p);
    if (z == kNoZone || (!route_scratch_.empty() && route_scratch_.back() == z)) return;
    if (route_scratch_.size() == capacity) {
      fits = false;
      return;
    }
    route_scratch_.push_back(z);
  };
  for (std::size_t i = 0; i < waypoints.size() && fits; ++i) {
    if (i > 0) {
      const Eigen::Vector3d a = waypoints[i - 1];
      const Eigen::Vector3d d = waypoints[i] - a;
      const double steps = std::ceil(d.norm() / kRouteSampleStepM);
      for (double s = 1.0; s < steps && fits; s += 1.0) note(a + d * (s / steps));
    }
    note(waypoints[i]);
  }
  if (!fits) return false;
  std::swap(route_, route_scratch_);  // capacities travel with the buffers: both reserved
  decide_->SetRoute(route_);
  return true;
}

BudgetChange TickLoop::SetBudget(std::uint64_t k_max) {
  BudgetChange c;
  c.requested = k_max;
  c.k_max = budget_.k_max;
  c.resident = working_set_->resident_count();
  if (k_max == 0) {
    c.outcome = BudgetChange::Outcome::kRefused;
    return c;
  }
  if (!Traits(config_.policy.kind).has_budget) {
    c.outcome = BudgetChange::Outcome::kIgnored;
    return c;
  }
  const std::uint32_t capacity = arena_.capacity();
  const auto applied = static_cast<std::uint32_t>(std::min<std::uint64_t>(k_max, capacity));
  c.outcome = k_max > capacity ? BudgetChange::Outcome::kClamped : BudgetChange::Outcome::kApplied;
  const Plan& plan = decide_->ChangeBudget(applied);
  TickTelemetry t;
  if (!plan.empty()) {
    const Status s = working_set_->Apply(plan, &t);
    if (!s.ok()) {
      ++totals_.step_errors;
      if (totals_.first_error.ok()) totals_.first_error = s;
    }
  }
  totals_.keyframes_unloaded += t.keyframes_unloaded;
  totals_.unload_ms += t.unload_ms;
  budget_.k_max = applied;
  c.k_max = applied;
  c.resident = working_set_->resident_count();
  c.unloaded = t.keyframes_unloaded;
  return c;
}

}  // namespace zm
