// Import of an RTAB-Map database (versions 0.19 to 0.23, basic-baseline.md §5) into a zonemap
// map database, keeping RTAB-Map's node ids as keyframe ids.
//
//   Node     48-byte pose (12 LE float32, row-major 3x4); weight -9 (invalid) nodes skipped
//   Link     stored twice (a->b and b->a): one edge per (min id, max id, type), from < to;
//            self links (pose prior, gravity) and landmark links (to_id < 0) skipped
//   Data     JPEG image, RVL or PNG depth (decoded to validate them), calibration -> camera
//   Feature  raw 32-byte binary descriptors, keypoints (pos_x, pos_y), 3-D points (depth_x/y/z
//            in the node's frame, moved to the map frame with the node's pose); or, with
//            RtabmapFeatureSource::kOrb, ORB features extracted from Data.image and Data.depth
//   Admin    opt_ids / opt_poses (zlib + 12-byte trailer) used as the map poses when present
//   Info     the last working memory: the imported nodes whose Node.time_enter >= the last
//            Info.time_enter, RTAB-Map's own query for its start-up with
//            Mem/InitWMWithAllNodes=false (DBDriverSqlite3 loadLastNodesQuery; basic-baseline.md
//            §3.4), recorded with MapDbWriter::SetLastWorkingMemory. Without an Info row with a
//            time or without time_enter columns there is nothing to go by: "every node" is
//            recorded, and the report says why.
//
// Columns are discovered with PRAGMA table_info, never assumed. NULL blobs and pose-only maps
// are fine. A damaged blob stops the import with one error naming the node (or link), the
// column and the sizes. OUT is written as OUT.tmp and renamed only when complete, so a crash or
// an error never leaves a broken OUT (an existing OUT is untouched unless the import succeeds).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/status.h"
#include "import/orb_keyframe.h"
#include "localization/map_vocabulary.h"
#include "localization/orb_extractor.h"
#include "mapdb/map_db.h"

namespace zm {

// Where a keyframe's features come from.
//   kRtabmap  RTAB-Map's own Feature rows (keypoints, 3-D points, 32-byte descriptors), as the
//             import did before issue 26: the map keeps RTAB-Map's features exactly and the
//             import decodes no image for them. The default, so an import of a database whose
//             nodes have Feature rows but no images (RTAB-Map's Mem/BinDataKept=false) still
//             has features.
//   kOrb      zonemap's one ORB extractor (lib/localization/orb_extractor.h) on each node's
//             Data.image and Data.depth: the keyframes then hold the same features the loop
//             extracts from camera frames (a vocabulary and PnP against the map need that), and
//             nodes without Feature rows get features too. Keypoints are in the calibration's
//             pixels, 3-D points decoded from the stored depth (lib/import/orb_keyframe.h); the
//             vocabulary is trained from the keyframes and stored. A node without an image or a
//             depth keeps no features (counted).
enum class RtabmapFeatureSource { kRtabmap, kOrb };

struct RtabmapImportOptions {
  RtabmapFeatureSource features = RtabmapFeatureSource::kRtabmap;
  OrbOptions orb;                   // kOrb: the extractor's options
  DenseKeyframeOptions dense;       // kOrb: the payload's JPEG quality and cloud step
  MapVocabularyOptions vocabulary;  // kOrb: trained and stored after the import
  bool overwrite = false;           // replace OUT if it exists
  bool keep_dense = true;           // carry the colour/depth bytes into the payloads
  bool use_optimized_poses = true;  // Admin.opt_poses as map poses when present
  WriteProgressFn progress;         // stages "nodes", "links"
};

struct RtabmapImportReport {
  std::string rtabmap_version;           // Admin.version, empty when absent
  std::uint64_t nodes = 0;               // Node rows read
  std::uint64_t keyframes = 0;           // imported
  std::uint64_t skipped_invalid = 0;     // weight -9
  std::uint64_t skipped_null_pose = 0;   // NULL or all-zero pose and no optimized pose
  std::uint64_t optimized_poses = 0;     // keyframes whose pose came from Admin.opt_poses
  std::uint64_t link_rows = 0;           // Link rows read
  std::uint64_t links = 0;               // edges written
  std::uint64_t links_duplicate = 0;     // second copies of an edge
  std::uint64_t links_self = 0;          // from == to (pose prior, gravity)
  std::uint64_t links_landmark = 0;      // to_id < 0
  std::uint64_t links_dangling = 0;      // an end was not imported
  std::uint64_t features = 0;            // imported into payloads
  std::uint64_t features_skipped = 0;    // no 32-byte descriptor or no finite 3-D point
  std::uint64_t images = 0;              // colour images carried
  std::uint64_t depths = 0;              // depth images carried
  std::uint64_t stereo_right_dropped = 0;  // depth column held a right image (stereo)
  std::uint32_t largest_payload_bytes = 0;
  std::uint64_t total_payload_bytes = 0;
  bool has_camera = false;
  CameraIntrinsics camera;
  bool last_wm_recorded = false;         // a last working memory was found (else: every node)
  std::uint64_t last_wm_nodes = 0;       // its size (imported nodes only)
  std::string last_info_time_enter;      // MAX(Info.time_enter), empty when none
  // --features orb:
  std::uint64_t orb_keyframes = 0;             // nodes whose features ORB extracted
  std::uint64_t orb_nodes_without_images = 0;  // no colour or no depth: no features
  double extract_ms = 0.0;                     // ORB extraction, total
  bool vocabulary_trained = false;             // false: not asked, or no feature to train on
  MapVocabularyReport vocabulary;
  double ms = 0.0;
};

// Imports `in_path` (read-only) into a new zonemap map database at `out_path`.
[[nodiscard]] Result<RtabmapImportReport> ImportRtabmap(const std::string& in_path,
                                                        const std::string& out_path,
                                                        const RtabmapImportOptions& options = {});

// ---- Building blocks (exposed for tests and tools) -------------------------------------------

// RTAB-Map's compressData2: zlib stream + 12-byte trailer of 3 int32 (rows, cols, OpenCV type).
struct RtabmapMatrix {
  std::int32_t rows = 0;
  std::int32_t cols = 0;
  std::int32_t type = 0;  // CV_8U=0 ... CV_64F=6, + 8 * (channels - 1)
  std::vector<std::byte> data;
};
// Bytes per element of an OpenCV type: the depth (type & 7: 8U 8S 16U 16S 32S 32F 64F 16F, OpenCV 4's
// numbering, whose 7 is CV_16F) times the channels (1 + type >> 3). The one table the decoder and
// its fuzz target's oracle both use.
[[nodiscard]] std::size_t RtabmapElementBytes(std::int32_t type);
// Errors name `what` (e.g. "Admin.opt_poses") and the sizes; the decompressed size must equal
// rows * cols * RtabmapElementBytes(type) exactly.
[[nodiscard]] Result<RtabmapMatrix> UncompressRtabmapData(std::span<const std::byte> blob,
                                                          const std::string& what);
[[nodiscard]] std::vector<std::byte> CompressRtabmapData(const RtabmapMatrix& m);

// CameraModel::serialize() (RTAB-Map >= 0.18): 11 int32 header, float64 K D R P, float32[12].
// Returns the first camera's intrinsics.
[[nodiscard]] Result<CameraIntrinsics> ParseRtabmapCalibration(std::span<const std::byte> blob);

}  // namespace zm
