// Localization on the resident working set (see localizer.h for the algorithm and invariants).
#include "localization/localizer.h"

#include <cassert>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>

#include "common/elapsed.h"
#include "localization/camera.h"

namespace zm {
namespace {

double HeadingDiff(double a, double b) {
  double d = std::remainder(a - b, 2.0 * std::numbers::pi);  // in [-pi, pi]
  return std::abs(d);
}

using Clock = std::chrono::steady_clock;

PnpParams PnpParamsFrom(const LocalizerConfig& c) {
  return {.reprojection_px = c.ransac_reprojection_px,
          .iterations = c.ransac_iterations,
          .confidence = c.ransac_confidence,
          .refine = c.refine,
          .seed = c.ransac_seed};
}

}  // namespace

Status ValidateLocalizerConfig(const LocalizerConfig& c, const CameraIntrinsics& k) {
  if (!(c.radius_m > 0.0)) return InvalidArgument("localizer radius_m must be > 0");
  if (!(c.max_heading_diff_rad > 0.0)) {
    return InvalidArgument("localizer max_heading_diff_rad must be > 0");
  }
  if (c.max_candidates == 0 || c.max_candidates > kMaxLocalizerCandidates) {
    return InvalidArgument("localizer max_candidates must be in [1, " +
                           std::to_string(kMaxLocalizerCandidates) + "], got " +
                           std::to_string(c.max_candidates));
  }
  if (c.appearance_candidates > c.max_candidates) {
    return InvalidArgument("localizer appearance_candidates must be <= max_candidates");
  }
  if (!(c.ratio > 0.0f && c.ratio <= 1.0f))
    return InvalidArgument("localizer ratio must be in (0, 1]");
  if (c.max_hamming > 256) return InvalidArgument("localizer max_hamming must be <= 256");
  if (c.min_inliers < 6) return InvalidArgument("localizer min_inliers must be >= 6");
  if (!(c.ransac_reprojection_px > 0.0) || c.ransac_iterations <= 0 ||
      !(c.ransac_confidence > 0.0 && c.ransac_confidence < 1.0)) {
    return InvalidArgument("localizer RANSAC parameters out of range");
  }
  if (c.word_features == 0) return InvalidArgument("localizer word_features must be >= 1");
  if (!(c.min_likelihood >= 0.0f && c.min_likelihood <= 1.0f)) {
    return InvalidArgument("localizer min_likelihood must be in [0, 1]");
  }
  if (!(c.max_correction_m >= 0.0))
    return InvalidArgument("localizer max_correction_m must be >= 0");
  if (Status g = ValidateClosureGateOptions(c.gate); !g.ok()) return g;
  if (!(k.fx > 0.0 && k.fy > 0.0) || k.width == 0 || k.height == 0) {
    return InvalidArgument("camera intrinsics must have fx, fy > 0 and a non-empty image");
  }
  return Status::Ok();
}

Localizer::Localizer(LocalizerConfig config, CameraIntrinsics camera)
    : config_(config),
      camera_(camera),
      pnp_(camera, PnpParamsFrom(config), config.reserve_features),
      scores_(config.reserve_keyframes, 0),
      matches_(config.reserve_features),
      gate_(config.gate) {
  assert(ValidateLocalizerConfig(config_, camera_).ok());
  object_points_.reserve(config.reserve_features);
  image_points_.reserve(config.reserve_features);
}

Status Localizer::UseVocabulary(const Vocabulary* vocabulary, std::uint32_t max_slots) {
  if (vocabulary == nullptr || vocabulary->word_count() == 0) {
    return InvalidArgument("localizer vocabulary is empty");
  }
  const InvertedIndexOptions o{.word_count = vocabulary->word_count(),
                               .max_keyframes = max_slots,
                               .max_words_per_keyframe = config_.word_features};
  ZM_RETURN_IF_ERROR(ValidateInvertedIndexOptions(o));
  vocabulary_ = vocabulary;
  index_ = std::make_unique<InvertedIndex>(o);
  bag_ = BowVector(config_.word_features);
  slot_id_.assign(max_slots, 0);
  slot_seen_.assign(max_slots, 0);
  slot_resident_.assign(max_slots, 0);
  indexed_slots_.clear();
  indexed_slots_.reserve(max_slots);
  top_.resize(kMaxIndexCandidates);
  scores_f_.assign(max_slots, 0.0f);  // per resident keyframe: at most one a slot
  return Status::Ok();
}

namespace {

// Per slot: the keyframe indexed there, the tick it was last seen, its index into the resident
// span, its place in indexed_slots_, its likelihood.
constexpr std::size_t kVocabularyBytesPerSlot =
    sizeof(std::int64_t) + sizeof(std::uint64_t) + 2 * sizeof(std::uint32_t) + sizeof(float);
// A bag of `words`: its entries and Transform's word scratch (BowVector).
std::size_t BagBytes(std::size_t words) {
  return words * (sizeof(BowEntry) + sizeof(std::uint32_t));
}

}  // namespace

std::size_t VocabularyIndexBytes(std::uint32_t word_count, std::uint32_t max_slots,
                                 std::uint32_t word_features) {
  const InvertedIndexOptions o{.word_count = word_count,
                               .max_keyframes = max_slots,
                               .max_words_per_keyframe = word_features};
  return InvertedIndex::BytesFor(o) + std::size_t{max_slots} * kVocabularyBytesPerSlot +
         BagBytes(word_features) + kMaxIndexCandidates * sizeof(IndexCandidate);
}

std::size_t Localizer::index_memory_bytes() const {
  if (index_ == nullptr) return 0;
  // The capacities UseVocabulary reserved, each table by its own.
  return index_->memory_bytes() + slot_id_.capacity() * sizeof(std::int64_t) +
         slot_seen_.capacity() * sizeof(std::uint64_t) +
         slot_resident_.capacity() * sizeof(std::uint32_t) +
         indexed_slots_.capacity() * sizeof(std::uint32_t) + scores_f_.capacity() * sizeof(float) +
         BagBytes(bag_.capacity()) + top_.capacity() * sizeof(IndexCandidate);
}

void Localizer::SyncIndex(std::span<const ResidentKeyframe> resident, LocalizeResult* r) {
  const std::uint64_t tick = stats_.ticks;  // already counted: > 0, so 0 means "never seen"
  const auto slots = static_cast<std::uint32_t>(slot_id_.size());
  for (std::size_t i = 0; i < resident.size(); ++i) {
    const ResidentKeyframe& kf = resident[i];
    const std::uint32_t s = kf.slot.value;
    if (s >= slots) continue;  // no slot given: it cannot be indexed, and scores 0
    slot_seen_[s] = tick;
    slot_resident_[s] = static_cast<std::uint32_t>(i);
    if (slot_id_[s] == kf.id.value) continue;
    if (slot_id_[s] != 0) {  // another keyframe now lives in this slot
      (void)index_->Remove(kf.slot);
      ++r->index_removed;
    } else {
      indexed_slots_.push_back(s);
    }
    const std::uint32_t words = std::min(kf.view.feature_count, config_.word_features);
    slot_id_[s] = kf.id.value;
    if (vocabulary_->Transform(kf.view.descriptors, words, &bag_).ok() &&
        index_->Add(kf.slot, kf.id, bag_).ok()) {
      ++r->index_added;
    }
  }
  // Keyframes no longer resident leave the index.
  for (std::size_t j = 0; j < indexed_slots_.size();) {
    const std::uint32_t s = indexed_slots_[j];
    if (slot_seen_[s] == tick) {
      ++j;
      continue;
    }
    if (index_->contains(SlotIndex{s})) (void)index_->Remove(SlotIndex{s});
    slot_id_[s] = 0;
    ++r->index_removed;
    indexed_slots_[j] = indexed_slots_.back();
    indexed_slots_.pop_back();
  }
}

void Localizer::ScoreByVocabulary(const Frame& frame, std::span<const ResidentKeyframe> resident,
                                  LocalizeResult* r) {
  auto t0 = Clock::now();
  const std::uint32_t words = std::min(frame.feature_count(), config_.word_features);
  const bool bag_ok = vocabulary_->Transform(frame.descriptors.front().data(), words, &bag_).ok();
  r->quantize_ms = MsSince(t0);
  t0 = Clock::now();
  std::fill(scores_f_.begin(), scores_f_.begin() + static_cast<std::ptrdiff_t>(resident.size()), 0.0f);
  if (bag_ok) {
    const std::size_t k = index_->Score(bag_, kMaxIndexCandidates, top_);
    r->postings_walked = index_->last_postings_walked();
    for (std::size_t c = 0; c < k; ++c) {
      const std::uint32_t i = slot_resident_[top_[c].slot.value];
      scores_f_[i] = top_[c].score;
    }
    // Top candidates come best first, ties to the larger id: the first is the hypothesis.
    if (k > 0 && top_[0].score >= config_.min_likelihood) {
      r->highest_hypothesis = top_[0].id;
      r->highest_likelihood = top_[0].score;
      r->highest_score = static_cast<std::uint32_t>(std::lround(top_[0].score * 1000.0f));
    }
  }
  r->likelihood_ms = MsSince(t0);
}

void Localizer::Offer(const Candidate& c, std::uint32_t limit,
                      std::array<Candidate, kMaxLocalizerCandidates>* list, std::uint32_t* size) {
  auto better = [](const Candidate& a, const Candidate& b) {
    return a.key > b.key || (a.key == b.key && a.id > b.id);
  };
  if (*size == limit && !better(c, (*list)[*size - 1])) return;
  std::uint32_t pos = *size < limit ? (*size)++ : limit - 1;
  while (pos > 0 && better(c, (*list)[pos - 1])) {
    (*list)[pos] = (*list)[pos - 1];
    --pos;
  }
  (*list)[pos] = c;
}

LocalizeResult Localizer::Localize(const Frame& frame, const Pose3& predicted_map_pose,
                                   std::span<const ResidentKeyframe> resident) {
  LocalizeResult r;
  ++stats_.ticks;
  gate_.Advance(frame.odom);  // every frame, also those that cannot close: the path since a fix
  const std::uint32_t n = frame.feature_count();
  if (frame.keypoints.size() != 2 * static_cast<std::size_t>(n)) {
    r.bad_frame = true;
    ++stats_.bad_frames;
    return r;
  }
  if (n == 0) return r;
  if (resident.empty()) {
    if (vocabulary_ != nullptr) SyncIndex(resident, &r);  // an emptied working set leaves it too
    return r;
  }
  const std::uint8_t* frame_desc = frame.descriptors.front().data();
  if (scores_.size() < resident.size()) scores_.resize(resident.size());  // grows once
  if (matches_.size() < n) matches_.resize(n);                            // grows once

  // 1. Appearance scores of every resident keyframe, and the highest hypothesis: the
  //    vocabulary's likelihood through the inverted index, or the binary-word scorer.
  const bool vocab = vocabulary_ != nullptr;
  if (vocab) {
    if (scores_f_.size() < resident.size()) scores_f_.resize(resident.size());  // grows once
    const auto t_index = Clock::now();
    SyncIndex(resident, &r);
    r.index_ms = MsSince(t_index);
    if (config_.use_appearance) ScoreByVocabulary(frame, resident, &r);
  }
  const auto t_verify = Clock::now();
  std::uint32_t best_score = 0;
  std::int64_t best_id = 0;
  if (config_.use_appearance && !vocab) {
    appearance_.SetQuery(frame_desc, n);
    for (std::size_t i = 0; i < resident.size(); ++i) {
      const KeyframeView& v = resident[i].view;
      scores_[i] = appearance_.Score(v.descriptors, v.feature_count);
      const std::int64_t id = resident[i].id.value;
      if (scores_[i] > best_score || (scores_[i] == best_score && id > best_id)) {
        best_score = scores_[i];
        best_id = id;
      }
    }
    appearance_.ClearQuery(frame_desc, n);
    if (best_score >= config_.min_appearance_score && best_score > 0) {
      r.highest_hypothesis = KeyframeId{best_id};
      r.highest_score = best_score;
    }
  }
  // One appearance key per resident keyframe, and whether it may be a candidate at all.
  const auto appearance_key = [&](std::size_t i) {
    return vocab ? static_cast<double>(scores_f_[i]) : static_cast<double>(scores_[i]);
  };
  const auto appearance_ok = [&](std::size_t i) {
    return vocab ? scores_f_[i] >= config_.min_likelihood && scores_f_[i] > 0.0f
                 : scores_[i] >= config_.min_appearance_score;
  };

  // 2. Candidates: the top appearance keyframes anywhere, and the pose-gated ones.
  std::array<Candidate, kMaxLocalizerCandidates> global{};
  std::uint32_t global_size = 0;
  if (config_.use_appearance && config_.appearance_candidates > 0) {
    for (std::size_t i = 0; i < resident.size(); ++i) {
      if (!appearance_ok(i)) continue;
      Offer({static_cast<std::uint32_t>(i), appearance_key(i), resident[i].id.value},
            config_.appearance_candidates, &global, &global_size);
    }
  }
  std::array<Candidate, kMaxLocalizerCandidates> list{};
  std::uint32_t list_size = 0;
  const Eigen::Vector3d predicted_t = predicted_map_pose.translation();
  const double predicted_yaw = Yaw(predicted_map_pose);
  for (std::size_t i = 0; i < resident.size(); ++i) {
    const double dist = (resident[i].pose.translation() - predicted_t).norm();
    const bool in_gate =
        dist <= config_.radius_m &&
        HeadingDiff(Yaw(resident[i].pose), predicted_yaw) <= config_.max_heading_diff_rad;
    bool in_global = false;
    for (std::uint32_t g = 0; g < global_size; ++g) in_global = in_global || global[g].index == i;
    if (!in_gate && !in_global) continue;
    if (config_.use_appearance && !appearance_ok(i)) continue;
    const double key = config_.use_appearance ? appearance_key(i) : -dist;
    Offer({static_cast<std::uint32_t>(i), key, resident[i].id.value}, config_.max_candidates, &list,
          &list_size);
  }

  // 3. Match and verify, best candidate first, until one is accepted.
  const simd::RatioTestParams ratio{config_.ratio, config_.max_hamming};
  for (std::uint32_t c = 0; c < list_size && !r.accepted; ++c) {
    const ResidentKeyframe& kf = resident[list[c].index];
    const KeyframeView& v = kf.view;
    ++r.candidates_examined;
    if (v.points == nullptr) {  // a dense keyframe whose depth was not decoded: no 3-D points
      ++r.closures_rejected;
      continue;
    }
    const std::size_t m =
        simd::MatchRatioTest(frame_desc, n, v.descriptors, v.feature_count, ratio, matches_.data());
    r.matches = static_cast<std::uint32_t>(m);
    if (m < config_.min_inliers) {
      ++r.closures_rejected;
      continue;
    }
    object_points_.clear();
    image_points_.clear();
    // Points decoded from depth are in the keyframe's camera frame (RTAB-Map keeps words3 in the
    // node's frame too): the keyframe's pose puts them in the map. No depth there: no point.
    const bool in_camera = v.points_frame == PointFrame::kCamera;
    const Pose3 t_map_kf_cam = in_camera ? CameraPoseInMap(kf.pose) : Pose3::Identity();
    for (std::size_t k = 0; k < m; ++k) {
      const float* p = v.points + std::size_t{matches_[k].train} * 3;
      if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
      const float* uv = frame.keypoints.data() + std::size_t{matches_[k].query} * 2;
      if (in_camera) {
        const Eigen::Vector3d q = t_map_kf_cam * Eigen::Vector3f(p[0], p[1], p[2]).cast<double>();
        object_points_.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()),
                                    static_cast<float>(q.z()));
      } else {
        object_points_.emplace_back(p[0], p[1], p[2]);
      }
      image_points_.emplace_back(uv[0], uv[1]);
    }
    if (object_points_.size() < config_.min_inliers) {
      ++r.closures_rejected;
      continue;
    }
    const PnpSolution solved = pnp_.Solve(object_points_, image_points_);
    if (solved.outcome != PnpOutcome::kOk && solved.outcome != PnpOutcome::kNoConsensus) {
      ++r.pnp_errors;  // bad input or only degenerate samples: not an ordinary failed closure
      ++r.closures_rejected;
      continue;
    }
    if (!solved.found || solved.inliers < config_.min_inliers) {
      ++r.closures_rejected;
      continue;
    }
    const Pose3 t_map_cam = solved.t_cam_map.inverse();
    const Pose3 t_map_body = BodyPoseFromCamera(t_map_cam);
    if (config_.max_correction_m > 0.0 &&
        (t_map_body.translation() - predicted_t).norm() > config_.max_correction_m) {
      ++r.closures_rejected;
      continue;
    }
    if (!gate_.Check(t_map_body, predicted_map_pose)) {
      ++r.inconsistent;
      ++r.closures_rejected;
      continue;
    }
    gate_.Accepted();
    r.relocalized = gate_.relocalized();
    r.accepted = true;
    r.matched = kf.id;
    r.inliers = solved.inliers;
    r.t_map_cam = t_map_cam;
    r.t_map_body = t_map_body;
    r.body_covariance = BodyCovarianceFromCamera(solved.covariance, t_map_cam);
    r.reprojection_rms_px = solved.rms_px;
    r.closures_accepted = 1;
  }
  r.verify_ms = MsSince(t_verify);
  stats_.closures_accepted += r.closures_accepted;
  stats_.closures_rejected += r.closures_rejected;
  stats_.candidates_examined += r.candidates_examined;
  stats_.pnp_errors += r.pnp_errors;
  stats_.inconsistent += r.inconsistent;
  stats_.relocalized += r.relocalized ? 1 : 0;
  return r;
}

Pose3 MapFromOdomCorrection(const Pose3& t_map_cam, const Pose3& t_odom_body) {
  const Pose3 t_odom_cam = t_odom_body * BodyToCamera();
  return t_map_cam * t_odom_cam.inverse();
}

Eigen::Matrix<double, 6, 6> BodyCovarianceFromCamera(
    const Eigen::Matrix<double, 6, 6>& t_cam_map_covariance, const Pose3& t_map_cam) {
  Eigen::Matrix<double, 6, 6> m = Eigen::Matrix<double, 6, 6>::Zero();
  m.topLeftCorner<3, 3>() = t_map_cam.linear();
  m.bottomRightCorner<3, 3>() = t_map_cam.linear();
  return m * t_cam_map_covariance * m.transpose();
}

}  // namespace zm
