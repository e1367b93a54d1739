// Occupancy grid loaders (ROS YAML, plain image, RTAB-Map Admin.opt_map) and cell<->metre
// conversion. Every OpenCV, zlib and sqlite3 failure becomes a Status naming the file.
#include "segment/grid_map.h"

#include <sqlite3.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <vector>

namespace zm {
namespace {

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::string Unquote(const std::string& s) {
  if (s.size() >= 2 && (s.front() == '"' || s.front() == '\'') && s.back() == s.front()) {
    return s.substr(1, s.size() - 2);
  }
  return s;
}

Result<double> ParseDouble(const std::string& file, const std::string& key,
                           const std::string& text) {
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    return InvalidArgument(file + ": key '" + key + "' is not a number: '" + text + "'");
  }
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Classifies one grey value by map_server's rules (p = occupancy probability in [0, 1]).
std::uint8_t Classify(double p, double occupied_thresh, double free_thresh) {
  if (p > occupied_thresh) return kCellOccupied;
  if (p < free_thresh) return kCellFree;
  return kCellUnknown;
}

// Reads an image as 8-bit grey plus an alpha mask (255 where opaque).
Result<std::pair<cv::Mat, cv::Mat>> ReadGreyAndAlpha(const std::string& path) {
  ZM_ASSIGN_OR_RETURN(cv::Mat img, ReadImageFile(path, cv::IMREAD_UNCHANGED));
  try {
    if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 257.0);
    if (img.depth() != CV_8U) {
      return InvalidArgument(path + ": unsupported pixel depth (8 or 16 bit expected)");
    }
    cv::Mat grey;
    cv::Mat alpha(img.size(), CV_8UC1, cv::Scalar(255));
    switch (img.channels()) {
      case 1:
        grey = img;
        break;
      case 3:
        cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
        break;
      case 4:
        cv::cvtColor(img, grey, cv::COLOR_BGRA2GRAY);
        cv::extractChannel(img, alpha, 3);
        break;
      default:
        return InvalidArgument(path + ": unsupported channel count " +
                               std::to_string(img.channels()));
    }
    return std::make_pair(grey, alpha);
  } catch (const cv::Exception& e) {
    return InvalidArgument(path + ": " + e.what());
  }
}

struct YamlMap {
  std::string image;
  double resolution = 0.0;
  double origin[3] = {0.0, 0.0, 0.0};
  bool negate = false;
  double occupied_thresh = 0.65;
  double free_thresh = 0.196;
  std::string mode = "trinary";
};

}  // namespace

Result<cv::Mat> ReadImageFile(const std::string& path, int imread_flags) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return NotFound(path + ": no such file");
  cv::Mat img;
  try {
    img = cv::imread(path, imread_flags);
  } catch (const cv::Exception& e) {
    return InvalidArgument(path + ": OpenCV could not read it: " + e.what());
  }
  if (img.empty()) return InvalidArgument(path + ": not a readable image (PNG, PGM, ...)");
  return img;
}

Eigen::Vector2d OccupancyGrid::CellToMetres(double col, double row) const {
  return {origin_m.x() + (col + 0.5) * resolution_m,
          origin_m.y() + (static_cast<double>(cells.rows) - row - 0.5) * resolution_m};
}

Eigen::Vector2d OccupancyGrid::MetresToCell(const Eigen::Vector2d& p_m) const {
  return {(p_m.x() - origin_m.x()) / resolution_m,
          static_cast<double>(cells.rows) - (p_m.y() - origin_m.y()) / resolution_m};
}

bool OccupancyGrid::CellOf(const Eigen::Vector2d& p_m, int* col, int* row) const {
  const Eigen::Vector2d c = MetresToCell(p_m);
  if (!std::isfinite(c.x()) || !std::isfinite(c.y())) return false;
  const double fc = std::floor(c.x());
  const double fr = std::floor(c.y());
  if (fc < 0 || fr < 0 || fc >= cells.cols || fr >= cells.rows) return false;
  *col = static_cast<int>(fc);
  *row = static_cast<int>(fr);
  return true;
}

Result<OccupancyGrid> LoadGridImage(const std::string& image_path, double resolution_m) {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    return InvalidArgument(image_path +
                           ": resolution must be a positive number of metres per "
                           "pixel, got " +
                           std::to_string(resolution_m));
  }
  ZM_ASSIGN_OR_RETURN(auto grey_alpha, ReadGreyAndAlpha(image_path));
  const cv::Mat& grey = grey_alpha.first;
  const cv::Mat& alpha = grey_alpha.second;
  OccupancyGrid grid;
  grid.resolution_m = resolution_m;
  grid.cells.create(grey.size(), CV_8UC1);
  for (int r = 0; r < grey.rows; ++r) {
    const auto* g = grey.ptr<std::uint8_t>(r);
    const auto* a = alpha.ptr<std::uint8_t>(r);
    auto* out = grid.cells.ptr<std::uint8_t>(r);
    for (int c = 0; c < grey.cols; ++c) {
      if (a[c] < 128) {
        out[c] = kCellUnknown;
      } else if (g[c] >= 250) {
        out[c] = kCellFree;
      } else if (g[c] <= 50) {
        out[c] = kCellOccupied;
      } else {
        out[c] = kCellUnknown;
      }
    }
  }
  return grid;
}

Result<OccupancyGrid> LoadGridYaml(const std::string& yaml_path) {
  std::ifstream in(yaml_path);
  if (!in) return NotFound(yaml_path + ": cannot open the map YAML");
  YamlMap y;
  std::set<std::string> seen;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    line = Trim(line);
    if (line.empty() || line == "---") continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) {
      return InvalidArgument(yaml_path + ":" + std::to_string(line_no) +
                             ": expected 'key: value', got '" + line + "'");
    }
    const std::string key = Trim(line.substr(0, colon));
    const std::string value = Unquote(Trim(line.substr(colon + 1)));
    const std::string where = yaml_path + ":" + std::to_string(line_no);
    seen.insert(key);
    if (key == "image") {
      y.image = value;
    } else if (key == "resolution") {
      ZM_ASSIGN_OR_RETURN(y.resolution, ParseDouble(where, key, value));
      if (!(y.resolution > 0.0)) {
        return InvalidArgument(where + ": resolution must be > 0 metres per pixel, got " + value);
      }
    } else if (key == "origin") {
      if (value.size() < 2 || value.front() != '[' || value.back() != ']') {
        return InvalidArgument(where + ": origin must be [x, y, yaw], got '" + value + "'");
      }
      std::stringstream ss(value.substr(1, value.size() - 2));
      std::string item;
      int n = 0;
      while (std::getline(ss, item, ',')) {
        if (n >= 3) return InvalidArgument(where + ": origin has more than 3 values");
        ZM_ASSIGN_OR_RETURN(y.origin[n], ParseDouble(where, key, Trim(item)));
        ++n;
      }
      if (n != 3) return InvalidArgument(where + ": origin must have 3 values [x, y, yaw]");
      if (std::abs(y.origin[2]) > 1e-9) {
        return Unsupported(where + ": rotated maps (origin yaw != 0) are not supported");
      }
    } else if (key == "negate") {
      const std::string v = Lower(value);
      if (v == "0" || v == "false") {
        y.negate = false;
      } else if (v == "1" || v == "true") {
        y.negate = true;
      } else {
        return InvalidArgument(where + ": negate must be 0 or 1, got '" + value + "'");
      }
    } else if (key == "occupied_thresh") {
      ZM_ASSIGN_OR_RETURN(y.occupied_thresh, ParseDouble(where, key, value));
    } else if (key == "free_thresh") {
      ZM_ASSIGN_OR_RETURN(y.free_thresh, ParseDouble(where, key, value));
    } else if (key == "mode") {
      y.mode = value;
      if (y.mode != "trinary" && y.mode != "scale" && y.mode != "raw") {
        return InvalidArgument(where + ": mode must be trinary, scale or raw, got '" + value + "'");
      }
    } else {
      return InvalidArgument(where + ": unknown key '" + key +
                             "' (known: image, resolution, origin, negate, occupied_thresh, "
                             "free_thresh, mode)");
    }
  }
  for (const char* required : {"image", "resolution", "origin"}) {
    if (!seen.count(required)) {
      return InvalidArgument(yaml_path + ": missing required key '" + required + "'");
    }
  }
  if (!(y.free_thresh >= 0.0 && y.free_thresh <= y.occupied_thresh && y.occupied_thresh <= 1.0)) {
    return InvalidArgument(yaml_path +
                           ": thresholds must satisfy 0 <= free_thresh <= "
                           "occupied_thresh <= 1");
  }
  std::filesystem::path image_path(y.image);
  if (image_path.is_relative()) {
    image_path = std::filesystem::path(yaml_path).parent_path() / image_path;
  }
  ZM_ASSIGN_OR_RETURN(auto grey_alpha, ReadGreyAndAlpha(image_path.string()));
  const cv::Mat& grey = grey_alpha.first;
  OccupancyGrid grid;
  grid.resolution_m = y.resolution;
  grid.origin_m = {y.origin[0], y.origin[1]};
  grid.cells.create(grey.size(), CV_8UC1);
  for (int r = 0; r < grey.rows; ++r) {
    const auto* g = grey.ptr<std::uint8_t>(r);
    const auto* a = grey_alpha.second.ptr<std::uint8_t>(r);
    auto* out = grid.cells.ptr<std::uint8_t>(r);
    for (int c = 0; c < grey.cols; ++c) {
      if (a[c] < 128) {
        out[c] = kCellUnknown;
        continue;
      }
      if (y.mode == "raw") {
        // Raw mode: the value is the occupancy in percent, 255 (or > 100) unknown.
        out[c] =
            g[c] > 100 ? kCellUnknown : Classify(g[c] / 100.0, y.occupied_thresh, y.free_thresh);
        continue;
      }
      const double p = y.negate ? g[c] / 255.0 : (255.0 - g[c]) / 255.0;
      out[c] = Classify(p, y.occupied_thresh, y.free_thresh);
    }
  }
  return grid;
}

Result<OccupancyGrid> DecodeRtabmapMapBlob(const std::string& blob, double x_min_m, double y_min_m,
                                           double resolution_m) {
  constexpr std::size_t kTrailer = 3 * sizeof(std::int32_t);
  if (blob.size() <= kTrailer) {
    return Corrupt("RTAB-Map opt_map blob is " + std::to_string(blob.size()) +
                   " bytes, shorter than its 12-byte trailer plus data");
  }
  std::int32_t trailer[3];
  std::memcpy(trailer, blob.data() + blob.size() - kTrailer, kTrailer);
  const std::int32_t rows = trailer[0], cols = trailer[1], type = trailer[2];
  if (type != CV_8SC1 && type != CV_8UC1) {
    return Unsupported("RTAB-Map opt_map has OpenCV type " + std::to_string(type) +
                       ", expected CV_8SC1 (" + std::to_string(CV_8SC1) + ")");
  }
  constexpr std::int32_t kMaxSide = 1 << 15;
  if (rows <= 0 || cols <= 0 || rows > kMaxSide || cols > kMaxSide) {
    return Corrupt("RTAB-Map opt_map size " + std::to_string(rows) + "x" + std::to_string(cols) +
                   " is outside 1.." + std::to_string(kMaxSide) + " cells per side");
  }
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    return Corrupt("RTAB-Map opt_map_resolution must be > 0, got " + std::to_string(resolution_m));
  }
  const auto expected = static_cast<uLongf>(rows) * static_cast<uLongf>(cols);
  std::vector<std::int8_t> raw(expected);
  uLongf got = expected;
  const int rc = uncompress(reinterpret_cast<Bytef*>(raw.data()), &got,
                            reinterpret_cast<const Bytef*>(blob.data()),
                            static_cast<uLong>(blob.size() - kTrailer));
  if (rc != Z_OK || got != expected) {
    return Corrupt("RTAB-Map opt_map does not inflate to " + std::to_string(rows) + "x" +
                   std::to_string(cols) + " cells (zlib code " + std::to_string(rc) + ", got " +
                   std::to_string(got) + " bytes)");
  }
  OccupancyGrid grid;
  grid.resolution_m = resolution_m;
  // RTAB-Map's x_min/y_min is the centre-less corner of cell (0, 0) (cells span
  // [x_min + c*res, x_min + (c+1)*res)), which after the flip is our bottom-left corner.
  grid.origin_m = {x_min_m, y_min_m};
  grid.cells.create(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    auto* out = grid.cells.ptr<std::uint8_t>(rows - 1 - r);  // flip: RTAB-Map row 0 = bottom
    const std::int8_t* in =
        raw.data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(cols);
    for (int c = 0; c < cols; ++c) {
      const int v = in[c];
      out[c] = v < 0 ? kCellUnknown : (v >= 50 ? kCellOccupied : kCellFree);
    }
  }
  return grid;
}

Result<OccupancyGrid> LoadRtabmapGrid(const std::string& db_path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(db_path, ec)) return NotFound(db_path + ": no such file");
  sqlite3* raw_db = nullptr;
  const int open_rc = sqlite3_open_v2(db_path.c_str(), &raw_db, SQLITE_OPEN_READONLY, nullptr);
  std::unique_ptr<sqlite3, decltype(&sqlite3_close)> db(raw_db, &sqlite3_close);
  if (open_rc != SQLITE_OK) {
    return IoError(db_path + ": cannot open as SQLite: " + sqlite3_errstr(open_rc));
  }
  sqlite3_stmt* raw_stmt = nullptr;
  const char* kSql =
      "SELECT opt_map, opt_map_x_min, opt_map_y_min, opt_map_resolution FROM Admin "
      "WHERE opt_map IS NOT NULL LIMIT 1";
  if (sqlite3_prepare_v2(db.get(), kSql, -1, &raw_stmt, nullptr) != SQLITE_OK) {
    return InvalidArgument(db_path + ": not an RTAB-Map database with an Admin.opt_map column (" +
                           sqlite3_errmsg(db.get()) + ")");
  }
  std::unique_ptr<sqlite3_stmt, decltype(&sqlite3_finalize)> stmt(raw_stmt, &sqlite3_finalize);
  const int step = sqlite3_step(stmt.get());
  if (step == SQLITE_DONE) {
    return NotFound(db_path + ": Admin.opt_map is empty (RTAB-Map saved no optimized grid)");
  }
  if (step != SQLITE_ROW) {
    return IoError(db_path + ": reading Admin.opt_map: " + sqlite3_errmsg(db.get()));
  }
  const void* bytes = sqlite3_column_blob(stmt.get(), 0);
  const int n = sqlite3_column_bytes(stmt.get(), 0);
  std::string blob(static_cast<const char*>(bytes), static_cast<std::size_t>(n));
  const double x_min = sqlite3_column_double(stmt.get(), 1);
  const double y_min = sqlite3_column_double(stmt.get(), 2);
  const double res = sqlite3_column_double(stmt.get(), 3);
  auto grid = DecodeRtabmapMapBlob(blob, x_min, y_min, res);
  if (!grid.ok()) return grid.status().Annotate(db_path);
  return grid;
}

Result<OccupancyGrid> LoadOccupancyGrid(const std::string& path, double resolution_m) {
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (ext == ".yaml" || ext == ".yml") {
    ZM_ASSIGN_OR_RETURN(auto grid, LoadGridYaml(path));
    if (resolution_m > 0.0) grid.resolution_m = resolution_m;
    return grid;
  }
  if (ext == ".db") return LoadRtabmapGrid(path);
  return LoadGridImage(path, resolution_m > 0.0 ? resolution_m : kDefaultGridResolutionM);
}

namespace segment_detail {

bool FreeAt(const cv::Mat& free, cv::Point2d p) {
  const long c = std::lround(p.x), r = std::lround(p.y);
  return r >= 0 && c >= 0 && r < free.rows && c < free.cols &&
         free.at<std::uint8_t>(static_cast<int>(r), static_cast<int>(c)) != 0;
}

int MedianFreeRun(const cv::Mat& free, cv::Point2d centre, cv::Point2d along, cv::Point2d step,
                  int steps, int cap) {
  std::vector<int> widths(Idx(std::max(steps, 1)), 0);
  for (int i = 0; i < steps; ++i) {
    const cv::Point2d p = centre + step * (i + 1);
    if (!FreeAt(free, p)) continue;
    int w = 1;
    for (int k = 1; k <= cap && FreeAt(free, p + along * k); ++k) ++w;
    for (int k = 1; k <= cap && FreeAt(free, p - along * k); ++k) ++w;
    widths[Idx(i)] = w;
  }
  const auto median = widths.begin() + static_cast<std::ptrdiff_t>(widths.size() / 2);
  std::nth_element(widths.begin(), median, widths.end());
  return *median;
}

}  // namespace segment_detail
}  // namespace zm
