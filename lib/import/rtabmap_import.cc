// RTAB-Map database import; see rtabmap_import.h for what is read and how. The input is opened
// read-only and walked with three cursors in node-id order (Node, Data, Feature: a merge join,
// so no per-node query and no index is needed); keyframes are written in batches. OpenCV
// exceptions are caught here and become Status values.
#include "import/rtabmap_import.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <tuple>
#include <unordered_set>

#include "mapdb/keyframe_payload.h"
#include "mapdb/rvl.h"
#include "mapdb/sqlite_util.h"

namespace zm {
namespace {

using sqlite::FromSqlite;

constexpr std::size_t kPoseBytes = 48;          // 12 float32
constexpr std::size_t kInformationBytes = 288;  // 36 float64
constexpr std::size_t kBatch = 128;             // keyframes per write transaction

std::string Node(std::int64_t id) { return "node " + std::to_string(id); }

std::span<const std::byte> ColumnBytes(sqlite3_stmt* s, int col) {
  const void* p = sqlite3_column_blob(s, col);
  const int n = sqlite3_column_bytes(s, col);
  if (p == nullptr || n <= 0) return {};
  return {static_cast<const std::byte*>(p), static_cast<std::size_t>(n)};
}

// A 48-byte RTAB-Map Transform; nullopt for a NULL blob or the null (all-zero) transform.
Result<std::optional<Pose3>> ParseTransform(std::span<const std::byte> b, const std::string& what) {
  if (b.empty()) return std::optional<Pose3>{};
  if (b.size() != kPoseBytes) {
    return Corrupt(what + " is " + std::to_string(b.size()) + " bytes, expected " +
                   std::to_string(kPoseBytes) + " (12 float32)");
  }
  float v[12];
  std::memcpy(v, b.data(), sizeof v);
  bool all_zero = true;
  for (float f : v) {
    if (!std::isfinite(f)) return Corrupt(what + " holds a non-finite value");
    all_zero &= f == 0.0f;
  }
  if (all_zero) return std::optional<Pose3>{};
  Pose3 p = Pose3::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.linear()(r, c) = static_cast<double>(v[r * 4 + c]);
    p.translation()(r) = static_cast<double>(v[r * 4 + 3]);
  }
  return std::optional<Pose3>{p};
}

bool StartsWith(std::span<const std::byte> b, std::initializer_list<unsigned char> magic) {
  if (b.size() < magic.size()) return false;
  std::size_t i = 0;
  for (unsigned char m : magic) {
    if (b[i++] != static_cast<std::byte>(m)) return false;
  }
  return true;
}
bool IsJpeg(std::span<const std::byte> b) { return StartsWith(b, {0xFF, 0xD8, 0xFF}); }
bool IsPng(std::span<const std::byte> b) { return StartsWith(b, {0x89, 'P', 'N', 'G'}); }

Result<cv::Mat> DecodeImage(std::span<const std::byte> b, const std::string& what) {
  try {
    const cv::Mat raw(1, static_cast<int>(b.size()), CV_8UC1,
                      const_cast<std::byte*>(b.data()));  // imdecode only reads it
    cv::Mat img = cv::imdecode(raw, cv::IMREAD_UNCHANGED);
    if (img.empty()) {
      return Corrupt(what + " of " + std::to_string(b.size()) + " bytes does not decode as an image");
    }
    return img;
  } catch (const cv::Exception& e) {
    return Corrupt(what + " of " + std::to_string(b.size()) + " bytes: OpenCV: " + e.what());
  }
}

Result<std::vector<std::byte>> EncodeImage(const cv::Mat& img, const char* ext, const std::string& what) {
  try {
    std::vector<uchar> buf;
    if (!cv::imencode(ext, img, buf)) return Internal(what + ": cv::imencode(" + ext + ") failed");
    std::vector<std::byte> out(buf.size());
    std::memcpy(out.data(), buf.data(), buf.size());
    return out;
  } catch (const cv::Exception& e) {
    return Internal(what + ": cv::imencode(" + ext + "): " + e.what());
  }
}

std::vector<std::byte> Bytes(std::span<const std::byte> b) { return {b.begin(), b.end()}; }

struct Columns {
  std::vector<std::string> names;
  [[nodiscard]] bool Has(const std::string& n) const {
    for (const auto& c : names) {
      if (c == n) return true;
    }
    return false;
  }
  // The column name if present, else NULL (so one SELECT fits every version).
  [[nodiscard]] std::string Or(const std::string& n) const { return Has(n) ? n : "NULL"; }
};

Result<Columns> ColumnsOf(sqlite3* db, const std::string& table) {
  ZM_ASSIGN_OR_RETURN(auto names, sqlite::TableColumns(db, table));
  return Columns{std::move(names)};
}

struct NodeRow {
  std::int64_t id = 0;
  std::int32_t weight = 0;
  double stamp = 0.0;
  Pose3 pose = Pose3::Identity();
};

// The dense part of a payload built from a node's Data row.
struct Dense {
  DenseFormat format = DenseFormat::kNone;
  std::vector<std::byte> bytes;
  std::uint32_t split = 0;
};

Result<Dense> BuildDense(std::int64_t id, std::span<const std::byte> image,
                         std::span<const std::byte> depth, RtabmapImportReport& report) {
  Dense d;
  std::vector<std::byte> jpeg;
  if (!image.empty()) {
    const std::string what = Node(id) + ": Data.image";
    ZM_ASSIGN_OR_RETURN(cv::Mat img, DecodeImage(image, what));
    if (IsJpeg(image)) {
      jpeg = Bytes(image);
    } else {  // PNG colour (Mem/ImageCompressionFormat=.png): the payload format says JPEG
      ZM_ASSIGN_OR_RETURN(jpeg, EncodeImage(img, ".jpg", what));
    }
    ++report.images;
  }
  std::vector<std::byte> png_depth, rvl_depth;
  if (!depth.empty()) {
    const std::string what = Node(id) + ": Data.depth";
    if (IsRvlDepth(depth)) {
      auto rvl = DecodeRvlDepth(depth);
      if (!rvl.ok()) return rvl.status().Annotate(what);
      if (jpeg.empty()) {
        rvl_depth = Bytes(depth);
      } else {  // no "RVL + JPEG" payload format: carry the depth as PNG
        cv::Mat m(static_cast<int>(rvl->height), static_cast<int>(rvl->width), CV_16UC1,
                  rvl->pixels.data());
        ZM_ASSIGN_OR_RETURN(png_depth, EncodeImage(m, ".png", what));
      }
      ++report.depths;
    } else {
      ZM_ASSIGN_OR_RETURN(cv::Mat m, DecodeImage(depth, what));
      if (m.type() == CV_16UC1) {
        if (IsPng(depth)) {
          png_depth = Bytes(depth);
        } else {
          ZM_ASSIGN_OR_RETURN(png_depth, EncodeImage(m, ".png", what));
        }
        ++report.depths;
      } else if (m.type() == CV_8UC4) {  // 32FC1 metres stored as the bytes of an 8UC4 PNG
        cv::Mat metres(m.rows, m.cols, CV_32FC1, m.data);
        cv::Mat mm(m.rows, m.cols, CV_16UC1);
        for (int r = 0; r < m.rows; ++r) {
          for (int c = 0; c < m.cols; ++c) {
            const float v = metres.at<float>(r, c) * 1000.0f;
            mm.at<std::uint16_t>(r, c) =
                std::isfinite(v) && v > 0.0f && v < 65535.0f ? static_cast<std::uint16_t>(v + 0.5f) : 0;
          }
        }
        ZM_ASSIGN_OR_RETURN(png_depth, EncodeImage(mm, ".png", what));
        ++report.depths;
      } else if (m.type() == CV_8UC1 || m.type() == CV_8UC3) {
        ++report.stereo_right_dropped;  // stereo: the column holds the right image
      } else {
        return Unsupported(what + ": decoded image of OpenCV type " + std::to_string(m.type()) +
                           " is neither 16UC1 depth, 32FC1 depth nor a right image");
      }
    }
  }
  if (!png_depth.empty() && !jpeg.empty()) {
    d.format = DenseFormat::kPngDepthAndJpegColour;
    d.split = static_cast<std::uint32_t>(png_depth.size());
    d.bytes = std::move(png_depth);
    d.bytes.insert(d.bytes.end(), jpeg.begin(), jpeg.end());
  } else if (!png_depth.empty()) {
    d.format = DenseFormat::kPngDepth16;
    d.bytes = std::move(png_depth);
  } else if (!rvl_depth.empty()) {
    d.format = DenseFormat::kRvlDepth16;
    d.bytes = std::move(rvl_depth);
  } else if (!jpeg.empty()) {
    d.format = DenseFormat::kJpegColour;
    d.bytes = std::move(jpeg);
  }
  return d;
}

// Reads Admin.opt_ids / opt_poses into id -> pose; empty when absent or NULL.
Result<std::map<std::int64_t, Pose3>> ReadOptimizedPoses(sqlite3* db, RtabmapImportReport& report) {
  std::map<std::int64_t, Pose3> poses;
  ZM_ASSIGN_OR_RETURN(const bool has_admin, sqlite::TableExists(db, "Admin"));
  if (!has_admin) return poses;
  ZM_ASSIGN_OR_RETURN(const Columns admin, ColumnsOf(db, "Admin"));
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt s,
                      sqlite::Prepare(db, "SELECT " + admin.Or("version") + ", " +
                                              admin.Or("opt_ids") + ", " + admin.Or("opt_poses") +
                                              " FROM Admin"));
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    if (const auto* v = sqlite3_column_text(s.get(), 0); v != nullptr && report.rtabmap_version.empty()) {
      report.rtabmap_version = reinterpret_cast<const char*>(v);
    }
    const auto ids_blob = ColumnBytes(s.get(), 1);
    const auto poses_blob = ColumnBytes(s.get(), 2);
    if (ids_blob.empty() || poses_blob.empty() || !poses.empty()) continue;
    ZM_ASSIGN_OR_RETURN(const RtabmapMatrix ids, UncompressRtabmapData(ids_blob, "Admin.opt_ids"));
    ZM_ASSIGN_OR_RETURN(const RtabmapMatrix ps, UncompressRtabmapData(poses_blob, "Admin.opt_poses"));
    if (ids.type != CV_32SC1) {
      return Corrupt("Admin.opt_ids has OpenCV type " + std::to_string(ids.type) + ", expected " +
                     std::to_string(CV_32SC1) + " (int32)");
    }
    if (ps.type != CV_32FC1) {
      return Corrupt("Admin.opt_poses has OpenCV type " + std::to_string(ps.type) + ", expected " +
                     std::to_string(CV_32FC1) + " (float32)");
    }
    const std::size_t n = ids.data.size() / 4;
    if (ps.data.size() != n * kPoseBytes) {
      return Corrupt("Admin.opt_poses holds " + std::to_string(ps.data.size() / 4) + " floats for " +
                     std::to_string(n) + " ids in Admin.opt_ids (want 12 per id)");
    }
    for (std::size_t i = 0; i < n; ++i) {
      std::int32_t id;
      std::memcpy(&id, ids.data.data() + i * 4, 4);
      ZM_ASSIGN_OR_RETURN(auto pose, ParseTransform(std::span(ps.data).subspan(i * kPoseBytes, kPoseBytes),
                                                    "Admin.opt_poses[" + std::to_string(i) + "]"));
      if (pose) poses[id] = *pose;
    }
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "reading table Admin");
  return poses;
}

class Importer {
 public:
  Importer(std::string in, std::string out, const RtabmapImportOptions& options)
      : in_(std::move(in)), out_(std::move(out)), options_(options) {}

  Result<RtabmapImportReport> Run(MapDbWriter& writer) {
    ZM_ASSIGN_OR_RETURN(db_, sqlite::Open(in_, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX));
    sqlite3* db = db_.get();
    {
      auto has_node = sqlite::TableExists(db, "Node");
      if (!has_node.ok()) {
        return Corrupt(in_ + " is not a readable SQLite database (" +
                       sqlite::DescribeFileVsHeader(in_) + "): " + has_node.status().message());
      }
      if (!*has_node) return InvalidArgument(in_ + " is not an RTAB-Map database (no table Node)");
    }
    ZM_ASSIGN_OR_RETURN(auto optimized, ReadOptimizedPoses(db, report_));
    if (!options_.use_optimized_poses) optimized.clear();
    ZM_ASSIGN_OR_RETURN(std::vector<NodeRow> nodes, ReadNodes(optimized));
    ZM_RETURN_IF_ERROR(WriteKeyframes(writer, nodes));
    ZM_RETURN_IF_ERROR(WriteLinks(writer));
    ZM_RETURN_IF_ERROR(WriteLastWorkingMemory(writer));
    if (report_.has_camera) ZM_RETURN_IF_ERROR(writer.SetCamera(report_.camera));
    ZM_RETURN_IF_ERROR(writer.SetSource(
        "rtabmap:" + in_ + (report_.rtabmap_version.empty() ? "" : " v" + report_.rtabmap_version)));
    return report_;
  }

 private:
  Result<std::vector<NodeRow>> ReadNodes(const std::map<std::int64_t, Pose3>& optimized) {
    sqlite3* db = db_.get();
    ZM_ASSIGN_OR_RETURN(const Columns cols, ColumnsOf(db, "Node"));
    for (const char* need : {"id", "pose"}) {
      if (!cols.Has(need)) return InvalidArgument(in_ + ": table Node has no column " + need);
    }
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt s,
                        sqlite::Prepare(db, "SELECT id, " + cols.Or("weight") + ", " +
                                                cols.Or("stamp") + ", pose FROM Node ORDER BY id"));
    std::vector<NodeRow> nodes;
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      ++report_.nodes;
      NodeRow n;
      n.id = sqlite3_column_int64(s.get(), 0);
      n.weight = sqlite3_column_int(s.get(), 1);
      n.stamp = sqlite3_column_double(s.get(), 2);
      if (n.weight == -9) {
        ++report_.skipped_invalid;
        continue;
      }
      ZM_ASSIGN_OR_RETURN(auto raw, ParseTransform(ColumnBytes(s.get(), 3), Node(n.id) + ": Node.pose"));
      if (const auto it = optimized.find(n.id); it != optimized.end()) {
        n.pose = it->second;
        ++report_.optimized_poses;
      } else if (raw) {
        n.pose = *raw;
      } else {
        ++report_.skipped_null_pose;
        continue;
      }
      nodes.push_back(n);
    }
    if (rc != SQLITE_DONE) return FromSqlite(rc, db, in_ + ": reading table Node");
    return nodes;
  }

  // Statements over Data and Feature, stepped in node-id order alongside the nodes.
  Status PrepareCursors() {
    sqlite3* db = db_.get();
    ZM_ASSIGN_OR_RETURN(const bool has_data, sqlite::TableExists(db, "Data"));
    if (has_data) {
      ZM_ASSIGN_OR_RETURN(const Columns c, ColumnsOf(db, "Data"));
      ZM_ASSIGN_OR_RETURN(data_, sqlite::Prepare(db, "SELECT id, " + c.Or("image") + ", " +
                                                         c.Or("depth") + ", " + c.Or("calibration") +
                                                         " FROM Data ORDER BY id"));
      data_rc_ = sqlite3_step(data_.get());
    }
    std::string feature_table;
    for (const char* t : {"Feature", "Map_Node_Word"}) {
      ZM_ASSIGN_OR_RETURN(const bool has, sqlite::TableExists(db, t));
      if (has) {
        feature_table = t;
        break;
      }
    }
    if (!feature_table.empty()) {
      ZM_ASSIGN_OR_RETURN(const Columns c, ColumnsOf(db, feature_table));
      ZM_ASSIGN_OR_RETURN(
          feature_, sqlite::Prepare(db, "SELECT node_id, " + c.Or("word_id") + ", " + c.Or("pos_x") +
                                            ", " + c.Or("pos_y") + ", " + c.Or("depth_x") + ", " +
                                            c.Or("depth_y") + ", " + c.Or("depth_z") + ", " +
                                            c.Or("descriptor_size") + ", " + c.Or("descriptor") +
                                            " FROM " + feature_table + " ORDER BY node_id, rowid"));
      feature_rc_ = sqlite3_step(feature_.get());
    }
    ZM_ASSIGN_OR_RETURN(const bool has_word, sqlite::TableExists(db, "Word"));
    if (has_word) {
      ZM_ASSIGN_OR_RETURN(const Columns c, ColumnsOf(db, "Word"));
      if (c.Has("descriptor")) {
        ZM_ASSIGN_OR_RETURN(word_, sqlite::Prepare(db, "SELECT descriptor FROM Word WHERE id=?1"));
      }
    }
    return Status::Ok();
  }

  // Advances `s` (whose first column is the node id) past rows of nodes before `id`.
  Status Seek(sqlite3_stmt* s, int& rc, std::int64_t id, const char* table) {
    while (rc == SQLITE_ROW && sqlite3_column_int64(s, 0) < id) rc = sqlite3_step(s);
    if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
      return FromSqlite(rc, db_.get(), in_ + ": reading table " + std::string(table));
    }
    return Status::Ok();
  }

  struct Features {
    std::vector<Descriptor256> descriptors;
    std::vector<float> points, keypoints;
  };

  Status ReadFeatures(const NodeRow& n, Features& f) {
    f.descriptors.clear();
    f.points.clear();
    f.keypoints.clear();
    if (!feature_) return Status::Ok();
    sqlite3_stmt* s = feature_.get();
    ZM_RETURN_IF_ERROR(Seek(s, feature_rc_, n.id, "Feature"));
    for (; feature_rc_ == SQLITE_ROW && sqlite3_column_int64(s, 0) == n.id;
         feature_rc_ = sqlite3_step(s)) {
      std::span<const std::byte> desc = ColumnBytes(s, 8);
      if (desc.empty() && word_) {  // older maps keep descriptors only in the vocabulary
        sqlite3_stmt* w = word_.get();
        sqlite::StmtReset reset(w);
        sqlite3_bind_int64(w, 1, sqlite3_column_int64(s, 1));
        if (sqlite3_step(w) == SQLITE_ROW && ColumnBytes(w, 0).size() == kDescriptorBytes) {
          Descriptor256 d;
          std::memcpy(d.data(), ColumnBytes(w, 0).data(), kDescriptorBytes);
          ZM_RETURN_IF_ERROR(AddFeature(n, s, d, f));
        } else {
          ++report_.features_skipped;
        }
        continue;
      }
      if (desc.size() != kDescriptorBytes) {  // float or non-256-bit descriptors
        ++report_.features_skipped;
        continue;
      }
      Descriptor256 d;
      std::memcpy(d.data(), desc.data(), kDescriptorBytes);
      ZM_RETURN_IF_ERROR(AddFeature(n, s, d, f));
    }
    if (feature_rc_ != SQLITE_ROW && feature_rc_ != SQLITE_DONE) {
      return FromSqlite(feature_rc_, db_.get(), in_ + ": reading the features of " + Node(n.id));
    }
    return Status::Ok();
  }

  Status AddFeature(const NodeRow& n, sqlite3_stmt* s, const Descriptor256& d, Features& f) {
    const Eigen::Vector3d local(sqlite3_column_double(s, 4), sqlite3_column_double(s, 5),
                                sqlite3_column_double(s, 6));
    const bool has_point = sqlite3_column_type(s, 4) != SQLITE_NULL && local.allFinite() &&
                           !local.isZero(0.0);
    if (!has_point) {
      ++report_.features_skipped;
      return Status::Ok();
    }
    const Eigen::Vector3d p = n.pose * local;  // node frame -> map frame
    f.descriptors.push_back(d);
    for (int i = 0; i < 3; ++i) f.points.push_back(static_cast<float>(p(i)));
    f.keypoints.push_back(static_cast<float>(sqlite3_column_double(s, 2)));
    f.keypoints.push_back(static_cast<float>(sqlite3_column_double(s, 3)));
    ++report_.features;
    return Status::Ok();
  }

  // Positions the Data cursor on node n's row, the map's camera taken from the first
  // calibration met; false when the node has no Data row.
  Result<bool> SeekData(const NodeRow& n) {
    sqlite3_stmt* s = data_.get();
    ZM_RETURN_IF_ERROR(Seek(s, data_rc_, n.id, "Data"));
    if (data_rc_ != SQLITE_ROW || sqlite3_column_int64(s, 0) != n.id) return false;
    const auto calibration = ColumnBytes(s, 3);
    if (!calibration.empty() && !report_.has_camera) {
      auto cam = ParseRtabmapCalibration(calibration);
      if (!cam.ok()) return cam.status().Annotate(Node(n.id) + ": Data.calibration");
      report_.camera = *cam;
      report_.has_camera = true;
    }
    return true;
  }

  Status ReadDense(const NodeRow& n, Dense& dense) {
    dense = Dense{};
    if (!data_) return Status::Ok();
    ZM_ASSIGN_OR_RETURN(const bool has_row, SeekData(n));
    if (has_row && options_.keep_dense) {
      sqlite3_stmt* s = data_.get();
      ZM_ASSIGN_OR_RETURN(dense, BuildDense(n.id, ColumnBytes(s, 1), ColumnBytes(s, 2), report_));
    }
    return Status::Ok();
  }

  // --features orb: the node's payload from its Data.image and Data.depth through the one
  // extractor (orb_keyframe.h), or, without both images, the dense bytes alone and no features.
  Result<std::vector<std::byte>> OrbPayload(const NodeRow& n) {
    const KeyframeId id{n.id};
    const auto without_images = [&]() -> Result<std::vector<std::byte>> {
      ++report_.orb_nodes_without_images;
      Dense dense;
      if (data_ && data_rc_ == SQLITE_ROW && sqlite3_column_int64(data_.get(), 0) == n.id &&
          options_.keep_dense) {
        ZM_ASSIGN_OR_RETURN(dense, BuildDense(n.id, ColumnBytes(data_.get(), 1),
                                              ColumnBytes(data_.get(), 2), report_));
      }
      return EncodePayload(PayloadParts{id, {}, {}, {}, dense.format, dense.bytes, dense.split});
    };
    if (!data_) return without_images();
    ZM_ASSIGN_OR_RETURN(const bool has_row, SeekData(n));
    if (!has_row) return without_images();
    sqlite3_stmt* s = data_.get();
    const auto image = ColumnBytes(s, 1);
    const auto depth = ColumnBytes(s, 2);
    if (image.empty() || depth.empty()) return without_images();
    ZM_ASSIGN_OR_RETURN(cv::Mat colour, DecodeImage(image, Node(n.id) + ": Data.image"));
    DepthImage d;
    if (IsRvlDepth(depth)) {
      auto rvl = DecodeRvlDepth(depth);
      if (!rvl.ok()) return rvl.status().Annotate(Node(n.id) + ": Data.depth");
      d.image = cv::Mat(static_cast<int>(rvl->height), static_cast<int>(rvl->width), CV_16UC1,
                        rvl->pixels.data())
                    .clone();
      d.units_per_m = 1000.0;  // RTAB-Map's depth: millimetres
    } else {
      ZM_ASSIGN_OR_RETURN(cv::Mat m, DecodeImage(depth, Node(n.id) + ": Data.depth"));
      if (m.type() == CV_16UC1) {
        d.image = m;
        d.units_per_m = 1000.0;
      } else if (m.type() == CV_8UC4) {  // 32FC1 metres stored as the bytes of an 8UC4 PNG
        d.image = cv::Mat(m.rows, m.cols, CV_32FC1, m.data).clone();
      } else {
        return without_images();  // stereo: the column holds the right image, no depth
      }
    }
    if (!report_.has_camera) {
      return FailedPrecondition(Node(n.id) + ": --features orb needs the camera (Data.calibration), "
                                "and no node before it has one");
    }
    if (colour.type() != CV_8UC1 && colour.type() != CV_8UC3 && colour.type() != CV_8UC4) {
      return InvalidArgument(Node(n.id) + ": Data.image decodes to OpenCV type " +
                             std::to_string(colour.type()) + ", not 8-bit grey or colour");
    }
    if (d.image.size() != colour.size()) {  // depth registered at another resolution
      cv::resize(d.image, d.image, colour.size(), 0, 0, cv::INTER_NEAREST);
    }
    // The extractor sees the image at its own size: the calibration scaled to it.
    const CameraIntrinsics& cam = report_.camera;
    const double sx = static_cast<double>(colour.cols) / cam.width;
    const double sy = static_cast<double>(colour.rows) / cam.height;
    if (!extractor_ || extractor_->camera().width != static_cast<std::uint32_t>(colour.cols) ||
        extractor_->camera().height != static_cast<std::uint32_t>(colour.rows)) {
      const CameraIntrinsics scaled{cam.fx * sx, cam.fy * sy, cam.cx * sx, cam.cy * sy,
                                    static_cast<std::uint32_t>(colour.cols),
                                    static_cast<std::uint32_t>(colour.rows)};
      auto created = OrbExtractor::Create(options_.orb, scaled);
      if (!created.ok()) return created.status().Annotate(Node(n.id));
      extractor_.emplace(std::move(*created));
    }
    ZM_ASSIGN_OR_RETURN(OrbKeyframe kf,
                        BuildOrbKeyframe(*extractor_, orb_features_, colour, d, id, options_.dense,
                                         KeypointScale{1.0 / sx, 1.0 / sy}));
    ++report_.orb_keyframes;
    ++report_.images;
    ++report_.depths;
    report_.features += kf.features;
    report_.extract_ms += kf.extract_ms;
    return std::move(kf.payload);
  }

  Status WriteKeyframes(MapDbWriter& writer, const std::vector<NodeRow>& nodes) {
    ZM_RETURN_IF_ERROR(PrepareCursors());
    std::vector<std::vector<std::byte>> payloads;
    std::vector<KeyframeRecord> batch;
    payloads.reserve(kBatch);
    batch.reserve(kBatch);
    Features f;
    Dense dense;
    std::uint64_t done = 0;
    const auto flush = [&]() -> Status {
      for (std::size_t i = 0; i < batch.size(); ++i) batch[i].payload = payloads[i];
      ZM_RETURN_IF_ERROR(writer.InsertKeyframes(batch));
      batch.clear();
      payloads.clear();
      if (options_.progress) options_.progress("nodes", done, nodes.size());
      return Status::Ok();
    };
    for (const NodeRow& n : nodes) {
      std::vector<std::byte> payload;
      if (options_.features == RtabmapFeatureSource::kOrb) {
        ZM_ASSIGN_OR_RETURN(payload, OrbPayload(n));
      } else {
        ZM_RETURN_IF_ERROR(ReadFeatures(n, f));
        ZM_RETURN_IF_ERROR(ReadDense(n, dense));
        ZM_ASSIGN_OR_RETURN(payload,
                            EncodePayload(PayloadParts{KeyframeId{n.id}, f.descriptors, f.points,
                                                       f.keypoints, dense.format, dense.bytes,
                                                       dense.split}));
      }
      report_.largest_payload_bytes =
          std::max(report_.largest_payload_bytes, static_cast<std::uint32_t>(payload.size()));
      report_.total_payload_bytes += payload.size();
      KeyframeMeta meta;
      meta.id = KeyframeId{n.id};
      meta.stamp_s = n.stamp;
      meta.pose = n.pose;
      meta.weight = n.weight;
      meta.payload_bytes = static_cast<std::uint32_t>(payload.size());
      payloads.push_back(std::move(payload));
      batch.push_back(KeyframeRecord{meta, {}});
      imported_.insert(n.id);
      ++report_.keyframes;
      ++done;
      if (batch.size() == kBatch) ZM_RETURN_IF_ERROR(flush());
    }
    if (!batch.empty() || nodes.empty()) ZM_RETURN_IF_ERROR(flush());
    return Status::Ok();
  }

  Status WriteLinks(MapDbWriter& writer) {
    sqlite3* db = db_.get();
    ZM_ASSIGN_OR_RETURN(const bool has_link, sqlite::TableExists(db, "Link"));
    if (!has_link) return Status::Ok();
    ZM_ASSIGN_OR_RETURN(const Columns c, ColumnsOf(db, "Link"));
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt s,
                        sqlite::Prepare(db, "SELECT from_id, to_id, " + c.Or("type") + ", " +
                                                c.Or("transform") + ", " +
                                                c.Or("information_matrix") +
                                                " FROM Link ORDER BY from_id, to_id, type"));
    std::set<std::tuple<std::int64_t, std::int64_t, int>> seen;
    std::vector<LinkRecord> links;
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      ++report_.link_rows;
      std::int64_t from = sqlite3_column_int64(s.get(), 0);
      std::int64_t to = sqlite3_column_int64(s.get(), 1);
      const int type = sqlite3_column_int(s.get(), 2);
      if (to < 0 || from < 0) {
        ++report_.links_landmark;
        continue;
      }
      if (from == to) {
        ++report_.links_self;
        continue;
      }
      if (!imported_.contains(from) || !imported_.contains(to)) {
        ++report_.links_dangling;
        continue;
      }
      const std::string what = "link " + std::to_string(from) + "->" + std::to_string(to) +
                               " (type " + std::to_string(type) + ")";
      ZM_ASSIGN_OR_RETURN(auto t, ParseTransform(ColumnBytes(s.get(), 3), what + ": Link.transform"));
      if (!t) {
        ++report_.links_dangling;  // no usable constraint
        continue;
      }
      LinkRecord l;
      l.type = static_cast<LinkType>(type);
      const auto info = ColumnBytes(s.get(), 4);
      if (info.empty()) {
        for (int i = 0; i < 6; ++i) l.information[static_cast<std::size_t>(i * 7)] = 1.0;
      } else if (info.size() != kInformationBytes) {
        return Corrupt(what + ": Link.information_matrix is " + std::to_string(info.size()) +
                       " bytes, expected " + std::to_string(kInformationBytes) + " (36 float64)");
      } else {
        std::memcpy(l.information.data(), info.data(), kInformationBytes);
      }
      if (from > to) {  // the second copy of an edge, or the only one stored this way round
        std::swap(from, to);
        *t = t->inverse();
      }
      if (!seen.insert({from, to, type}).second) {
        ++report_.links_duplicate;
        continue;
      }
      l.from = KeyframeId{from};
      l.to = KeyframeId{to};
      l.transform = *t;
      links.push_back(l);
    }
    if (rc != SQLITE_DONE) return FromSqlite(rc, db, in_ + ": reading table Link");
    if (options_.progress) options_.progress("links", 0, links.size());
    ZM_RETURN_IF_ERROR(writer.InsertLinks(links));
    if (options_.progress) options_.progress("links", links.size(), links.size());
    report_.links = links.size();
    return Status::Ok();
  }

  // RTAB-Map's last working memory: Memory::loadDataFromDb loads it when
  // Mem/InitWMWithAllNodes is false, with loadLastNodesQuery's
  //   SELECT ... FROM Node WHERE time_enter >= (SELECT MAX(time_enter) FROM Info)
  // (Info since RTAB-Map 0.11.11; its row is written when a mapping session ends, after the
  // final working memory is re-stamped, so these are the nodes that session ended with). The
  // same SQL runs here on the same DATE text, so the comparison is SQLite's, as in RTAB-Map.
  Status WriteLastWorkingMemory(MapDbWriter& writer) {
    sqlite3* db = db_.get();
    const auto every_node = [&](const std::string& why) {
      return writer.SetLastWorkingMemoryEveryNode("every node: " + why);
    };
    ZM_ASSIGN_OR_RETURN(const bool has_info, sqlite::TableExists(db, "Info"));
    if (!has_info) return every_node("the RTAB-Map database has no table Info");
    ZM_ASSIGN_OR_RETURN(const Columns info, ColumnsOf(db, "Info"));
    ZM_ASSIGN_OR_RETURN(const Columns node, ColumnsOf(db, "Node"));
    if (!info.Has("time_enter") || !node.Has("time_enter")) {
      return every_node("the RTAB-Map database has no Info.time_enter or Node.time_enter");
    }
    {
      ZM_ASSIGN_OR_RETURN(sqlite::Stmt last, sqlite::Prepare(db, "SELECT MAX(time_enter) FROM Info"));
      const int rc = sqlite3_step(last.get());
      if (rc != SQLITE_ROW) return FromSqlite(rc, db, in_ + ": reading Info.time_enter");
      const auto* t = reinterpret_cast<const char*>(sqlite3_column_text(last.get(), 0));
      if (t == nullptr) return every_node("the RTAB-Map database has no Info row with a time_enter");
      report_.last_info_time_enter = t;
    }
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt s,
                        sqlite::Prepare(db, "SELECT id FROM Node WHERE time_enter >= (SELECT "
                                            "MAX(time_enter) FROM Info) ORDER BY id"));
    std::vector<KeyframeId> ids;
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      const std::int64_t id = sqlite3_column_int64(s.get(), 0);
      if (imported_.contains(id)) ids.push_back(KeyframeId{id});  // not invalid, has a pose
    }
    if (rc != SQLITE_DONE) return FromSqlite(rc, db, in_ + ": reading Node.time_enter");
    ZM_RETURN_IF_ERROR(writer.SetLastWorkingMemory(
        ids, "RTAB-Map Node.time_enter >= MAX(Info.time_enter) = '" + report_.last_info_time_enter +
                 "'"));
    report_.last_wm_recorded = true;
    report_.last_wm_nodes = ids.size();
    return Status::Ok();
  }

  std::string in_, out_;
  const RtabmapImportOptions& options_;
  sqlite::Db db_;
  sqlite::Stmt data_, feature_, word_;
  int data_rc_ = SQLITE_DONE;
  int feature_rc_ = SQLITE_DONE;
  std::unordered_set<std::int64_t> imported_;
  RtabmapImportReport report_;
  std::optional<OrbExtractor> extractor_;  // --features orb: for the images' size
  OrbFeatures orb_features_{options_.orb.max_features};
};

void RemoveDbFiles(const std::string& path) {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) std::filesystem::remove(path + suffix, ec);
}

}  // namespace

Result<RtabmapImportReport> ImportRtabmap(const std::string& in_path, const std::string& out_path,
                                          const RtabmapImportOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  std::error_code ec;
  if (!std::filesystem::exists(in_path, ec)) return NotFound("RTAB-Map database " + in_path + " does not exist");
  if (std::filesystem::exists(out_path, ec)) {
    if (std::filesystem::equivalent(in_path, out_path, ec)) {
      return InvalidArgument("input and output are the same file: " + in_path);
    }
    if (!options.overwrite) {
      return FailedPrecondition(out_path + " already exists (use --overwrite to replace it)");
    }
  }
  if (options.features == RtabmapFeatureSource::kOrb) {
    ZM_RETURN_IF_ERROR(ValidateOrbOptions(options.orb));
    ZM_RETURN_IF_ERROR(ValidateMapVocabularyOptions(options.vocabulary));
  }
  const std::string tmp = out_path + ".tmp";
  auto writer = MapDbWriter::Create(tmp, /*overwrite=*/true);
  if (!writer.ok()) return writer.status();
  Importer importer(in_path, out_path, options);
  auto report = importer.Run(**writer);
  Status st = report.ok() ? (*writer)->Finish() : report.status();
  writer->reset();  // closes the output before it is renamed or removed
  if (st.ok() && options.features == RtabmapFeatureSource::kOrb && report->features > 0) {
    // The vocabulary from the keyframes just written (lib/localization/map_vocabulary.h).
    auto vocabulary = TrainAndStoreMapVocabulary(tmp, options.vocabulary);
    if (vocabulary.ok()) {
      report->vocabulary = *vocabulary;
      report->vocabulary_trained = true;
    } else {
      st = vocabulary.status().Annotate("training the vocabulary");
    }
  }
  if (st.ok()) {
    std::filesystem::rename(tmp, out_path, ec);
    if (ec) st = IoError("renaming " + tmp + " to " + out_path + ": " + ec.message());
  }
  if (!st.ok()) {
    RemoveDbFiles(tmp);
    return st.Annotate("importing " + in_path);
  }
  report->ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace zm
