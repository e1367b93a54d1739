// Localization against the resident working set: the consumer that makes residency matter.
//
// Per tick, Localize():
//   1. scores every resident keyframe's global appearance for the frame (appearance.h, a bag of
//      binary words); the best one (score >= min_appearance_score, ties to the larger id, as
//      RTAB-Map's argmax) is `highest_hypothesis`, the id the basic policy retrieves around;
//   2. picks candidates: resident keyframes within radius_m of the predicted pose and within
//      max_heading_diff_rad of its heading, plus the top `appearance_candidates` by appearance
//      wherever they are (global loop closure after large drift); at most max_candidates,
//      best appearance first (nearest first when appearance is off);
//   3. for each candidate, in order, until one is accepted: matches the frame's descriptors to
//      the keyframe's (zm::simd kernels, Lowe ratio + absolute Hamming gate), pairs the frame
//      keypoints (2-D) with the keyframe's 3-D points (map frame, or camera frame for points
//      decoded from depth, put in the map with the keyframe's pose; points without depth are
//      skipped, a keyframe without decoded points is rejected), runs PnP-RANSAC (pnp.h) and
//      accepts when inliers >= min_inliers (and, if set, the correction is <= max_correction_m)
//      and the pose agrees with odometry (the closure gate, closure_gate.h: aliasing).
//
// Invariant 4 (docs/design.md): the localizer sees ONLY the keyframes it is handed, and the
// runtime hands it only resident ones (views into arena slots); a non-resident keyframe can
// never be a candidate, a hypothesis or a match. Views are read in place, never copied.
//
// Allocation: every scratch buffer (scores, matches, correspondences, word sets, PnP buffers) is
// sized in the constructor from reserve_features / reserve_keyframes; a tick within those sizes
// allocates nothing. A larger frame or working set grows a buffer once (then it is warm again).
// PnP-RANSAC is our own allocation-free solver (pnp.h), so a warm tick that verifies a candidate
// allocates nothing either (tests/localization/pnp_test.cc counts it).
//
// Pose conventions (camera.h): predicted pose and keyframe poses are BODY poses in the map
// frame (T_map_body); the PnP result is the CAMERA pose T_map_cam, with T_map_body beside it.
// The drift correction T_map_odom = T_map_cam * T_odom_cam^-1 is computed by the caller with
// MapFromOdomCorrection() and applied from the next tick.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <opencv2/core/types.hpp>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "localization/appearance.h"
#include "localization/closure_gate.h"
#include "localization/frame.h"
#include "localization/inverted_index.h"
#include "localization/pnp.h"
#include "localization/vocabulary.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "simd/hamming.h"

namespace zm {

inline constexpr std::uint32_t kNoResidentSlot = 0xFFFFFFFFu;

// One resident keyframe as the runtime passes it: id, body pose in the map, and the view into
// its arena slot.
struct ResidentKeyframe {
  KeyframeId id;
  Pose3 pose = Pose3::Identity();  // T_map_body of the keyframe
  KeyframeView view;
  SlotIndex slot{kNoResidentSlot};  // its arena slot: the vocabulary's inverted index is per slot
};

inline constexpr std::uint32_t kMaxLocalizerCandidates = 16;

struct LocalizerConfig {
  double radius_m = 10.0;                   // pose gate: 3-D distance to the predicted pose
  double max_heading_diff_rad = 1.5708;     // pose gate: |yaw difference| (90 degrees)
  std::uint32_t max_candidates = 3;         // tried per tick, <= kMaxLocalizerCandidates
  std::uint32_t appearance_candidates = 1;  // top appearance keyframes admitted outside the gate
  bool use_appearance = true;               // false: pose gate only, nearest first
  std::uint32_t min_appearance_score = 10;  // below: not a hypothesis, not a candidate
  float ratio = 0.8f;                       // Lowe ratio test
  std::uint32_t max_hamming = 64;           // absolute descriptor gate (bits of 256)
  std::uint32_t min_inliers = 20;           // accept a closure at this many PnP inliers
  double ransac_reprojection_px = 4.0;
  int ransac_iterations = 100;
  double ransac_confidence = 0.99;
  bool refine = true;                            // LM refinement on the inliers
  std::uint64_t ransac_seed = PnpParams{}.seed;  // PnP RNG seed, reapplied at every solve
  double max_correction_m = 0.0;          // reject a pose this far from the prediction; 0 = off
  // The consistency check of verified closures against odometry (closure_gate.h): rejects the
  // aliased ones (identical posters and wards), re-localizes when rejected ones agree.
  ClosureGateOptions gate;
  std::uint32_t reserve_features = 2048;  // scratch sizes: no allocation below these
  std::uint32_t reserve_keyframes = 4096;
  // With a vocabulary (UseVocabulary): the first word_features descriptors of a frame and of a
  // keyframe are its words (the extractor orders them strongest first: RTAB-Map's
  // Kp/MaxFeatures), and a keyframe whose DBoW2 L1 score is below min_likelihood is neither the
  // highest hypothesis nor a candidate (it replaces min_appearance_score's role).
  std::uint32_t word_features = 500;
  float min_likelihood = 0.02f;
};

// What Localizer::UseVocabulary reserves for a vocabulary of `word_count` words over `max_slots`
// arena slots with config.word_features words per keyframe: the memory budget counts it
// (runtime/budget.h) before the loop builds anything.
[[nodiscard]] std::size_t VocabularyIndexBytes(std::uint32_t word_count, std::uint32_t max_slots,
                                               std::uint32_t word_features);

// Checks ranges (counts, ratio in (0, 1], positive thresholds) and the camera; names the field.
[[nodiscard]] Status ValidateLocalizerConfig(const LocalizerConfig& config,
                                             const CameraIntrinsics& camera);

struct LocalizeResult {
  bool accepted = false;
  KeyframeId matched;             // keyframe that closed the loop (0 when none)
  KeyframeId highest_hypothesis;  // best appearance among resident keyframes (0 when none)
  std::uint32_t highest_score = 0;
  std::uint32_t inliers = 0;  // PnP inliers of the accepted candidate
  std::uint32_t matches = 0;  // descriptor matches of the accepted (or last tried) candidate
  Pose3 t_map_cam = Pose3::Identity();   // camera pose in the map (valid when accepted)
  Pose3 t_map_body = Pose3::Identity();  // body pose in the map (valid when accepted)
  // Covariance of t_map_body when accepted (BodyCovarianceFromCamera of the PnP solution's):
  // position in the map frame, then rotation about the map's axes (ROS PoseWithCovariance).
  Eigen::Matrix<double, 6, 6> body_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double reprojection_rms_px = 0.0;      // of the accepted solution's inliers
  std::uint32_t candidates_examined = 0;
  std::uint32_t closures_accepted = 0;  // 0 or 1 this tick
  std::uint32_t closures_rejected = 0;  // candidates examined and not accepted this tick
  std::uint32_t pnp_errors = 0;         // PnP input errors or all-degenerate samples (rejections)
  std::uint32_t inconsistent = 0;       // verified, but refused by the closure gate (rejections)
  bool relocalized = false;  // accepted because rejected closures agreed (closure_gate.h)
  bool bad_frame = false;               // keypoints.size() != 2 * descriptors.size()
  // With a vocabulary: the best resident keyframe's likelihood, the index's work, and where the
  // time went (ms): syncing the index with the resident set (keyframes entering or leaving:
  // their bags are computed here), the frame's bag, the likelihood over the index, and the
  // candidates' matching and PnP. Without one, verify_ms still holds steps 2-3.
  float highest_likelihood = 0.0f;
  std::uint64_t postings_walked = 0;
  std::uint32_t index_added = 0;
  std::uint32_t index_removed = 0;
  double index_ms = 0.0;
  double quantize_ms = 0.0;
  double likelihood_ms = 0.0;
  double verify_ms = 0.0;
};

// Totals since construction, for telemetry and the run summary.
struct LocalizerStats {
  std::uint64_t ticks = 0;
  std::uint64_t closures_accepted = 0;
  std::uint64_t closures_rejected = 0;
  std::uint64_t candidates_examined = 0;
  std::uint64_t pnp_errors = 0;
  std::uint64_t inconsistent = 0;  // verified closures the closure gate refused
  std::uint64_t relocalized = 0;   // closures accepted by agreement after refusals
  std::uint64_t bad_frames = 0;
};

class Localizer {
 public:
  // config must satisfy ValidateLocalizerConfig (asserted); allocates all scratch here.
  Localizer(LocalizerConfig config, CameraIntrinsics camera);

  // Localizes `frame` against `resident` (see the file comment). predicted_map_pose is the
  // body pose predicted by odometry and the current correction.
  [[nodiscard]] LocalizeResult Localize(const Frame& frame, const Pose3& predicted_map_pose,
                                        std::span<const ResidentKeyframe> resident);

  // From now on the appearance step is the vocabulary's likelihood: the frame's bag of words
  // scores the resident keyframes through an inverted index over arena slots (< max_slots: the
  // arena's slot count), which Localize keeps equal to the resident set it is handed (a
  // keyframe's bag is computed when it first appears in a slot, its postings dropped when it
  // leaves). `vocabulary` is not owned and must outlive the localizer. Allocates the index and
  // the bags here; kInvalidArgument when max_slots or the vocabulary is unusable.
  [[nodiscard]] Status UseVocabulary(const Vocabulary* vocabulary, std::uint32_t max_slots);
  [[nodiscard]] bool has_vocabulary() const { return vocabulary_ != nullptr; }
  // What UseVocabulary reserved (0 without a vocabulary): the inverted index, the per-slot tables
  // and the bags; equals VocabularyIndexBytes of its arguments (the memory budget's figure).
  [[nodiscard]] std::size_t index_memory_bytes() const;

  [[nodiscard]] const LocalizerStats& stats() const { return stats_; }
  [[nodiscard]] const LocalizerConfig& config() const { return config_; }

 private:
  struct Candidate {
    std::uint32_t index = 0;  // into `resident`
    double key = 0.0;         // larger is better
    std::int64_t id = 0;      // tie-break: larger id first
  };
  // Inserts into a best-first fixed array of at most `limit` entries.
  static void Offer(const Candidate& c, std::uint32_t limit,
                    std::array<Candidate, kMaxLocalizerCandidates>* list, std::uint32_t* size);

  // Brings the index to exactly `resident`'s keyframes; fills slot_resident_ (slot -> index into
  // resident, for the scores).
  void SyncIndex(std::span<const ResidentKeyframe> resident, LocalizeResult* r);
  // Scores every resident keyframe into scores_f_ (0 outside the index's top candidates) and
  // sets the highest hypothesis.
  void ScoreByVocabulary(const Frame& frame, std::span<const ResidentKeyframe> resident,
                         LocalizeResult* r);

  LocalizerConfig config_;
  CameraIntrinsics camera_;
  AppearanceScorer appearance_;
  const Vocabulary* vocabulary_ = nullptr;
  std::unique_ptr<InvertedIndex> index_;
  BowVector bag_{0};                             // the frame's, then each new keyframe's
  std::vector<std::int64_t> slot_id_;            // per slot: the keyframe indexed there (0: none)
  std::vector<std::uint64_t> slot_seen_;         // per slot: the last tick it was resident
  std::vector<std::uint32_t> slot_resident_;     // per slot: its index into this tick's resident
  std::vector<std::uint32_t> indexed_slots_;     // the slots in the index (unordered)
  std::vector<IndexCandidate> top_;              // Score's output
  std::vector<float> scores_f_;                  // per resident index: likelihood
  PnpRansac pnp_;
  std::vector<std::uint32_t> scores_;
  std::vector<simd::DescriptorMatch> matches_;
  std::vector<cv::Point3f> object_points_;
  std::vector<cv::Point2f> image_points_;
  ClosureGate gate_;
  LocalizerStats stats_;
};

// The drift correction from an accepted closure: T_map_odom = T_map_cam * T_odom_cam^-1 with
// T_odom_cam = t_odom_body * BodyToCamera(). Predicted pose next tick: T_map_odom * odom.
[[nodiscard]] Pose3 MapFromOdomCorrection(const Pose3& t_map_cam, const Pose3& t_odom_body);

// The body pose's covariance from a PnP solution's (pnp.h: left perturbation of T_cam_map).
// T_map_body = T_cam_map^-1 * BodyToCamera()^-1, so a left perturbation xi of T_cam_map is a
// right perturbation -Ad(BodyToCamera) xi of T_map_body, i.e. position and rotation errors of
// R_map_cam * (-v) and R_map_cam * (-w) in the map frame: C_body = M C_cam M^T with
// M = diag(R_map_cam, R_map_cam) (first order). Order: x y z, rotation about X Y Z (ROS).
[[nodiscard]] Eigen::Matrix<double, 6, 6> BodyCovarianceFromCamera(
    const Eigen::Matrix<double, 6, 6>& t_cam_map_covariance, const Pose3& t_map_cam);

}  // namespace zm
