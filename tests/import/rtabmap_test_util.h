// Builds RTAB-Map databases for the import tests, in RTAB-Map's own schema (basic-baseline.md
// §5, DatabaseSchema.sql.in): a 0.23 layout and a 0.19 layout whose tables lack later columns
// (Data.depth_confidence, Data.empty_cells, Node.env_sensors, the GlobalDescriptor table), so
// the importer must discover columns rather than assume them.
#pragma once

#include <doctest/doctest.h>
#include <sqlite3.h>

#include <cstring>
#include <string>
#include <vector>

#include "geometry/pose.h"
#include "import/rtabmap_import.h"

namespace zm::test {

inline constexpr const char* kRtabmapSchema023 = R"sql(
CREATE TABLE Admin (version TEXT, preview_image BLOB, opt_cloud BLOB, opt_ids BLOB, opt_poses BLOB,
  opt_last_localization BLOB, opt_polygons_size INTEGER, opt_polygons BLOB, opt_tex_coords BLOB,
  opt_tex_materials BLOB, opt_map BLOB, opt_map_x_min FLOAT, opt_map_y_min FLOAT,
  opt_map_resolution FLOAT, dictionary_index BLOB, time_enter DATE);
CREATE TABLE Node (id INTEGER NOT NULL, map_id INTEGER NOT NULL, weight INTEGER, stamp FLOAT,
  pose BLOB, ground_truth_pose BLOB, velocity BLOB, label TEXT, gps BLOB, env_sensors BLOB,
  time_enter DATE, PRIMARY KEY (id));
CREATE TABLE Data (id INTEGER NOT NULL, image BLOB, depth BLOB, depth_confidence BLOB,
  calibration BLOB, scan BLOB, scan_info BLOB, ground_cells BLOB, obstacle_cells BLOB,
  empty_cells BLOB, cell_size FLOAT, view_point_x FLOAT, view_point_y FLOAT, view_point_z FLOAT,
  user_data BLOB, time_enter DATE, PRIMARY KEY (id));
CREATE TABLE Link (from_id INTEGER NOT NULL, to_id INTEGER NOT NULL, type INTEGER NOT NULL,
  information_matrix BLOB NOT NULL, transform BLOB, user_data BLOB);
CREATE TABLE Word (id INTEGER NOT NULL, descriptor_size INTEGER NOT NULL,
  descriptor BLOB NOT NULL, time_enter DATE, PRIMARY KEY (id));
CREATE TABLE Feature (node_id INTEGER NOT NULL, word_id INTEGER NOT NULL, pos_x FLOAT NOT NULL,
  pos_y FLOAT NOT NULL, size INTEGER NOT NULL, dir FLOAT NOT NULL, response FLOAT NOT NULL,
  octave INTEGER NOT NULL, depth_x FLOAT, depth_y FLOAT, depth_z FLOAT, descriptor_size INTEGER,
  descriptor BLOB);
CREATE TABLE GlobalDescriptor (node_id INTEGER NOT NULL, type INTEGER NOT NULL, info BLOB,
  data BLOB NOT NULL);
CREATE TABLE Info (STM_size INTEGER, last_sign_added INTEGER, process_mem_used INTEGER,
  database_mem_used INTEGER, dictionary_size INTEGER, parameters TEXT, time_enter DATE);
CREATE TABLE Statistics (id INTEGER NOT NULL, stamp FLOAT, data BLOB, wm_state BLOB);
CREATE INDEX IDX_Feature_node_id on Feature (node_id);
CREATE INDEX IDX_Link_from_id on Link (from_id);
CREATE UNIQUE INDEX IDX_node_label on Node (label);
INSERT INTO Admin(version) VALUES('0.23.1');
)sql";

inline constexpr const char* kRtabmapSchema019 = R"sql(
CREATE TABLE Admin (version TEXT, preview_image BLOB, opt_cloud BLOB, opt_ids BLOB, opt_poses BLOB,
  opt_last_localization BLOB, opt_map BLOB, opt_map_x_min FLOAT, opt_map_y_min FLOAT,
  opt_map_resolution FLOAT, time_enter DATE);
CREATE TABLE Node (id INTEGER NOT NULL, map_id INTEGER NOT NULL, weight INTEGER, stamp FLOAT,
  pose BLOB, ground_truth_pose BLOB, velocity BLOB, label TEXT, gps BLOB, time_enter DATE,
  PRIMARY KEY (id));
CREATE TABLE Data (id INTEGER NOT NULL, image BLOB, depth BLOB, calibration BLOB, scan BLOB,
  scan_info BLOB, ground_cells BLOB, obstacle_cells BLOB, cell_size FLOAT, view_point_x FLOAT,
  view_point_y FLOAT, view_point_z FLOAT, user_data BLOB, time_enter DATE, PRIMARY KEY (id));
CREATE TABLE Link (from_id INTEGER NOT NULL, to_id INTEGER NOT NULL, type INTEGER NOT NULL,
  information_matrix BLOB NOT NULL, transform BLOB, user_data BLOB);
CREATE TABLE Word (id INTEGER NOT NULL, descriptor_size INTEGER NOT NULL,
  descriptor BLOB NOT NULL, time_enter DATE, PRIMARY KEY (id));
CREATE TABLE Feature (node_id INTEGER NOT NULL, word_id INTEGER NOT NULL, pos_x FLOAT NOT NULL,
  pos_y FLOAT NOT NULL, size INTEGER NOT NULL, dir FLOAT NOT NULL, response FLOAT NOT NULL,
  octave INTEGER NOT NULL, depth_x FLOAT, depth_y FLOAT, depth_z FLOAT, descriptor_size INTEGER,
  descriptor BLOB);
CREATE TABLE Info (STM_size INTEGER, last_sign_added INTEGER, process_mem_used INTEGER,
  database_mem_used INTEGER, dictionary_size INTEGER, parameters TEXT, time_enter DATE);
CREATE TABLE Statistics (id INTEGER NOT NULL, stamp FLOAT, data BLOB, wm_state BLOB);
CREATE INDEX IDX_Feature_node_id on Feature (node_id);
CREATE INDEX IDX_Link_from_id on Link (from_id);
INSERT INTO Admin(version) VALUES('0.19.3');
)sql";

using Blob = std::vector<std::byte>;

inline Blob PoseBlob(const Pose3& p) {
  float v[12];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) v[r * 4 + c] = static_cast<float>(p.linear()(r, c));
    v[r * 4 + 3] = static_cast<float>(p.translation()(r));
  }
  Blob b(sizeof v);
  std::memcpy(b.data(), v, sizeof v);
  return b;
}

inline Blob InformationBlob(double diag) {
  double m[36] = {};
  for (int i = 0; i < 6; ++i) m[i * 7] = diag;
  Blob b(sizeof m);
  std::memcpy(b.data(), m, sizeof m);
  return b;
}

inline Blob CalibrationBlob(double fx, double fy, double cx, double cy, int w, int h) {
  const std::int32_t header[11] = {0, 23, 1, 0, w, h, 9, 5, 9, 12, 12};
  const double k[9] = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
  const double d[5] = {};
  const double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double p[12] = {fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0};
  const float t[12] = {0, 0, 1, 0, -1, 0, 0, 0, 0, -1, 0, 0};
  Blob b;
  // resize + memcpy: GCC 12's aarch64 -O3 array-bounds analysis misreads vector::insert of
  // these differently sized arrays as an overflow.
  const auto put = [&](const void* src, std::size_t n) {
    const std::size_t at = b.size();
    b.resize(at + n);
    std::memcpy(b.data() + at, src, n);
  };
  put(header, sizeof header);
  put(k, sizeof k);
  put(d, sizeof d);
  put(r, sizeof r);
  put(p, sizeof p);
  put(t, sizeof t);
  return b;
}

// Compressed int32 ids / float32 poses as RTAB-Map writes Admin.opt_ids / opt_poses.
inline Blob OptIdsBlob(const std::vector<std::int32_t>& ids) {
  RtabmapMatrix m{1, static_cast<std::int32_t>(ids.size()), 4, Blob(ids.size() * 4)};
  std::memcpy(m.data.data(), ids.data(), m.data.size());
  return CompressRtabmapData(m);
}
inline Blob OptPosesBlob(const std::vector<Pose3>& poses) {
  RtabmapMatrix m{1, static_cast<std::int32_t>(12 * poses.size()), 5, {}};
  for (const auto& p : poses) {
    const Blob b = PoseBlob(p);
    m.data.insert(m.data.end(), b.begin(), b.end());
  }
  return CompressRtabmapData(m);
}

// A writable RTAB-Map database; NULL is bound for empty blobs.
class RtabDb {
 public:
  RtabDb(const std::string& path, const char* schema) {
    REQUIRE(sqlite3_open(path.c_str(), &db_) == SQLITE_OK);
    Exec("PRAGMA synchronous=OFF");  // a test fixture: no fsync needed
    Exec("BEGIN");
    Exec(schema);
  }
  ~RtabDb() { Close(); }
  RtabDb(const RtabDb&) = delete;
  RtabDb& operator=(const RtabDb&) = delete;
  void Close() {
    if (db_ == nullptr) return;
    Exec("COMMIT");
    sqlite3_close(db_);
    db_ = nullptr;
  }

  void Exec(const std::string& sql) {
    char* err = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
    INFO(sql << ": " << (err ? err : ""));
    sqlite3_free(err);
    REQUIRE(rc == SQLITE_OK);
  }
  // Runs `sql` with `args` bound in order: Blob (NULL when empty), double or int64.
  template <class... Args>
  void Run(const std::string& sql, const Args&... args) {
    sqlite3_stmt* s = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, sql.c_str(), -1, &s, nullptr) == SQLITE_OK);
    int i = 0;
    (Bind(s, ++i, args), ...);
    const int rc = sqlite3_step(s);
    sqlite3_finalize(s);
    INFO(sql);
    REQUIRE(rc == SQLITE_DONE);
  }

  void AddNode(std::int64_t id, int weight, const Blob& pose) {
    Run("INSERT INTO Node(id, map_id, weight, stamp, pose) VALUES(?, 0, ?, ?, ?)", id,
        std::int64_t{weight}, 0.1 * static_cast<double>(id), pose);
  }
  void AddLink(std::int64_t from, std::int64_t to, int type, const Blob& transform,
               const Blob& info = InformationBlob(1.0)) {
    Run("INSERT INTO Link(from_id, to_id, type, information_matrix, transform) VALUES(?, ?, ?, ?, ?)",
        from, to, std::int64_t{type}, info, transform);
  }

 private:
  static void Bind(sqlite3_stmt* s, int i, const Blob& b) {
    if (b.empty()) {
      sqlite3_bind_null(s, i);
    } else {
      sqlite3_bind_blob(s, i, b.data(), static_cast<int>(b.size()), SQLITE_TRANSIENT);
    }
  }
  static void Bind(sqlite3_stmt* s, int i, double v) { sqlite3_bind_double(s, i, v); }
  static void Bind(sqlite3_stmt* s, int i, std::int64_t v) { sqlite3_bind_int64(s, i, v); }
  static void Bind(sqlite3_stmt* s, int i, const std::string& v) {
    sqlite3_bind_text(s, i, v.c_str(), -1, SQLITE_TRANSIENT);
  }
  sqlite3* db_ = nullptr;
};

}  // namespace zm::test
