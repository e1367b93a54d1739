// Zone viewpoints and lookups, and real floor-plan import (see building.h). Floor-plan zones:
// every ground-truth colour blob is a room; free space outside every room becomes "corridor"
// zones (components of at least min_corridor_area_m2) or joins the nearest room; then every
// pixel of the image takes the label of the nearest labelled pixel (a discrete Voronoi fill), so
// the zones cover the whole map, and each label's outline (dilated by two pixels, so neighbours
// overlap slightly and no free cell falls between them) is simplified with approxPolyDP.
#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sim/building.h"
#include "zones/polygon.h"

namespace zm::sim {

bool InsidePolygon(const std::vector<Eigen::Vector2d>& ring, const Eigen::Vector2d& p) {
  bool inside = false;
  const std::size_t n = ring.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

int ZoneAt(const Building& building, int floor, const Eigen::Vector2d& p) {
  for (std::size_t i = 0; i < building.zones.size(); ++i) {
    const ZoneDef& z = building.zones[i];
    if (z.floor == floor && InsidePolygon(z.polygon, p)) return static_cast<int>(i);
  }
  return -1;
}

void FinishZones(Building* building) {
  std::vector<cv::Mat> clearance(building->floors.size());
  for (std::size_t f = 0; f < building->floors.size(); ++f) {
    const SimGrid& g = building->floors[f].grid;
    cv::Mat free_mask(g.rows, g.cols, CV_8UC1);
    for (int r = 0; r < g.rows; ++r) {
      auto* row = free_mask.ptr<std::uint8_t>(r);
      for (int c = 0; c < g.cols; ++c) row[c] = g.Free(c, r) ? 255 : 0;
    }
    cv::distanceTransform(free_mask, clearance[f], cv::DIST_L2, cv::DIST_MASK_5);
  }
  for (ZoneDef& z : building->zones) {
    const SimGrid& g = building->floors[static_cast<std::size_t>(z.floor)].grid;
    const cv::Mat& d = clearance[static_cast<std::size_t>(z.floor)];
    Eigen::Vector2d lo = z.polygon.front(), hi = z.polygon.front();
    for (const auto& p : z.polygon) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    int c0, r0, c1, r1;
    g.CellOf(lo, &c0, &r0);
    g.CellOf(hi, &c1, &r1);
    c0 = std::max(c0, 0);
    r0 = std::max(r0, 0);
    c1 = std::min(c1, g.cols - 1);
    r1 = std::min(r1, g.rows - 1);
    float best = 0.0f;
    z.viewpoint = (lo + hi) / 2.0;
    z.clearance_m = 0.0;
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        const float v = d.at<float>(r, c);
        if (v <= best) continue;
        const Eigen::Vector2d p = g.CellCentre(c, r);
        if (!InsidePolygon(z.polygon, p)) continue;
        best = v;
        z.viewpoint = p;
      }
    }
    z.clearance_m = static_cast<double>(best) * g.resolution_m;
  }
}

namespace {

// Image pixel (col, row), row 0 at the top, to map metres (origin at the bottom-left corner).
Eigen::Vector2d PixelToMetres(double col, double row, int rows, double res) {
  return {(col + 0.5) * res, (rows - row - 0.5) * res};
}

// The outline of `mask` (CV_8UC1, 255 inside) as a simple ring in metres: the largest external
// contour, simplified with growing tolerance until it is simple; the convex hull as a last resort.
std::vector<Eigen::Vector2d> MaskToRing(const cv::Mat& mask, double res) {
  // Padded so that a region touching the image edge is outlined outside the edge pixels, whose
  // centres are then strictly inside the ring.
  constexpr int kPad = 3;
  cv::Mat padded;
  cv::copyMakeBorder(mask, padded, kPad, kPad, kPad, kPad, cv::BORDER_CONSTANT, cv::Scalar(0));
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5));
  cv::dilate(padded, padded, kernel);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(padded, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  if (contours.empty()) return {};
  std::size_t best = 0;
  for (std::size_t i = 1; i < contours.size(); ++i) {
    if (cv::contourArea(contours[i]) > cv::contourArea(contours[best])) best = i;
  }
  const auto to_ring = [&](const std::vector<cv::Point>& pts) {
    std::vector<Eigen::Vector2d> ring;
    ring.reserve(pts.size());
    for (const auto& p : pts) ring.push_back(PixelToMetres(p.x - kPad, p.y - kPad, mask.rows, res));
    return ring;
  };
  for (const double eps : {0.7, 1.5, 3.0}) {
    std::vector<cv::Point> approx;
    cv::approxPolyDP(contours[best], approx, eps, true);
    if (approx.size() < 3) continue;
    auto ring = to_ring(approx);
    if (!FindSelfIntersection(ring) && std::abs(SignedArea(ring)) > 0.0) return ring;
  }
  std::vector<cv::Point> hull;
  cv::convexHull(contours[best], hull);
  return to_ring(hull);
}

}  // namespace

Result<Building> ImportFloorplan(const FloorplanOptions& o) {
  if (!(o.resolution_m > 0.0 && o.resolution_m <= 1.0)) {
    return InvalidArgument("floor plan resolution " + std::to_string(o.resolution_m) +
                           " m/px is outside (0, 1]");
  }
  cv::Mat img;
  try {
    img = cv::imread(o.map_path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return IoError("cannot read floor plan " + o.map_path + ": " + e.what());
  }
  if (img.empty()) return NotFound("cannot read floor plan image " + o.map_path);
  if (img.depth() != CV_8U) return InvalidArgument("floor plan " + o.map_path + " is not 8-bit");
  cv::Mat grey, alpha;
  if (img.channels() == 4) {
    cv::extractChannel(img, alpha, 3);
    cv::cvtColor(img, grey, cv::COLOR_BGRA2GRAY);
  } else if (img.channels() == 3) {
    cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  } else {
    grey = img;
  }
  cv::Mat gt;
  if (!o.gt_path.empty()) {
    try {
      gt = cv::imread(o.gt_path, cv::IMREAD_COLOR);
    } catch (const cv::Exception& e) {
      return IoError("cannot read ground truth " + o.gt_path + ": " + e.what());
    }
    if (gt.empty()) return NotFound("cannot read ground-truth image " + o.gt_path);
    if (std::abs(gt.cols - grey.cols) > 2 || std::abs(gt.rows - grey.rows) > 2) {
      return InvalidArgument("ground truth " + o.gt_path + " is " + std::to_string(gt.cols) + "x" +
                             std::to_string(gt.rows) + " but the map is " +
                             std::to_string(grey.cols) + "x" + std::to_string(grey.rows) +
                             " (at most 2 pixels of difference are cropped)");
    }
    const cv::Rect common(0, 0, std::min(gt.cols, grey.cols), std::min(gt.rows, grey.rows));
    gt = gt(common).clone();
    grey = grey(common).clone();
    if (!alpha.empty()) alpha = alpha(common).clone();
  }
  const int rows = grey.rows, cols = grey.cols;
  if (rows < 16 || cols < 16) return InvalidArgument("floor plan " + o.map_path + " is smaller than 16x16 px");
  const double res = o.resolution_m;

  // Occupancy, top-down like the image.
  cv::Mat occ(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::uint8_t v = grey.at<std::uint8_t>(r, c);
      const bool transparent = !alpha.empty() && alpha.at<std::uint8_t>(r, c) < 128;
      occ.at<std::uint8_t>(r, c) =
          transparent ? kCellUnknown : (v >= 230 ? kCellFree : (v <= 60 ? kCellOccupied : kCellUnknown));
    }
  }
  cv::Mat free_mask = occ == kCellFree;

  Building b;
  b.kind = "floorplan";
  b.area_m2 = cv::countNonZero(free_mask) * res * res;
  FloorMap floor;
  floor.grid = SimGrid::Filled(cols, rows, res, Eigen::Vector2d(0.0, 0.0), kCellUnknown);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) floor.grid.Set(c, rows - 1 - r, occ.at<std::uint8_t>(r, c));
  }
  floor.furniture.assign(floor.grid.cells.size(), 0);

  // Labels: 0 = none, 1.. = zone (rooms first, in colour order, then corridors).
  cv::Mat label(rows, cols, CV_32SC1, cv::Scalar(0));
  std::vector<std::pair<std::string, std::string>> names;  // (name, kind) per label - 1
  const double min_room_px = 1.0 / (res * res);             // 1 m2
  if (!gt.empty()) {
    std::map<std::uint32_t, int> colour_count;  // ordered: deterministic
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const cv::Vec3b v = gt.at<cv::Vec3b>(r, c);
        if (v[0] + v[1] + v[2] < 30) continue;  // black: no room
        ++colour_count[(std::uint32_t{v[2]} << 16) | (std::uint32_t{v[1]} << 8) | v[0]];
      }
    }
    for (const auto& [colour, count] : colour_count) {
      if (count < min_room_px) continue;
      const cv::Vec3b bgr(static_cast<std::uint8_t>(colour & 0xFF),
                          static_cast<std::uint8_t>((colour >> 8) & 0xFF),
                          static_cast<std::uint8_t>(colour >> 16));
      cv::Mat mask;
      cv::inRange(gt, bgr, bgr, mask);
      cv::Mat comp, stats, centroids;
      const int n = cv::connectedComponentsWithStats(mask, comp, stats, centroids, 8, CV_32S);
      for (int k = 1; k < n; ++k) {
        if (stats.at<int>(k, cv::CC_STAT_AREA) < min_room_px) continue;
        names.emplace_back("room" + std::to_string(names.size()), "room");
        label.setTo(static_cast<int>(names.size()), comp == k);
      }
    }
  }
  {
    // Free space outside every room: corridors, or the nearest room when small.
    cv::Mat rest = free_mask & (label == 0);
    cv::Mat comp, stats, centroids;
    const int n = cv::connectedComponentsWithStats(rest, comp, stats, centroids, 8, CV_32S);
    int n_corr = 0;
    for (int k = 1; k < n; ++k) {
      if (stats.at<int>(k, cv::CC_STAT_AREA) * res * res < o.min_corridor_area_m2 && !names.empty()) continue;
      if (gt.empty()) {
        // No ground truth: tile the component into 8 m squares.
        const int tile = std::max(1, static_cast<int>(std::lround(8.0 / res)));
        std::map<std::pair<int, int>, int> tile_label;
        for (int r = 0; r < rows; ++r) {
          for (int c = 0; c < cols; ++c) {
            if (comp.at<int>(r, c) != k) continue;
            const auto key = std::make_pair(r / tile, c / tile);
            auto it = tile_label.find(key);
            if (it == tile_label.end()) {
              names.emplace_back("tile" + std::to_string(names.size()), "room");
              it = tile_label.emplace(key, static_cast<int>(names.size())).first;
            }
            label.at<int>(r, c) = it->second;
          }
        }
      } else {
        names.emplace_back("corridor" + std::to_string(n_corr++), "corridor");
        label.setTo(static_cast<int>(names.size()), comp == k);
      }
    }
  }
  if (names.empty()) return InvalidArgument("floor plan " + o.map_path + " has no free space");

  // Voronoi fill: every pixel takes the label of the nearest labelled pixel.
  cv::Mat seeds = label == 0;  // non-zero where unlabelled; zero pixels are the seeds
  cv::Mat dist, voronoi;
  cv::distanceTransform(seeds, dist, voronoi, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<int> seed_label(static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) + 1, 0);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int l = label.at<int>(r, c);
      if (l != 0) seed_label[static_cast<std::size_t>(voronoi.at<int>(r, c))] = l;
    }
  }
  cv::Mat filled(rows, cols, CV_32SC1);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      filled.at<int>(r, c) = seed_label[static_cast<std::size_t>(voronoi.at<int>(r, c))];
    }
  }
  // One connected region per label: a stray piece (the Voronoi fill can cut one off) joins the
  // label that borders it most, so the single outline per zone still covers every pixel.
  const cv::Mat cross = cv::getStructuringElement(cv::MORPH_CROSS, cv::Size(3, 3));
  for (int pass = 0; pass < 3; ++pass) {
    bool changed = false;
    for (std::size_t i = 0; i < names.size(); ++i) {
      const int id = static_cast<int>(i + 1);
      cv::Mat comp, stats, centroids;
      const int n = cv::connectedComponentsWithStats(filled == id, comp, stats, centroids, 4, CV_32S);
      if (n <= 2) continue;
      int largest = 1;
      for (int k = 2; k < n; ++k) {
        if (stats.at<int>(k, cv::CC_STAT_AREA) > stats.at<int>(largest, cv::CC_STAT_AREA)) largest = k;
      }
      for (int k = 1; k < n; ++k) {
        if (k == largest) continue;
        const cv::Mat piece = comp == k;
        cv::Mat ring;
        cv::dilate(piece, ring, cross);
        ring &= ~piece;
        std::map<int, int> votes;
        for (int r = 0; r < rows; ++r) {
          for (int c = 0; c < cols; ++c) {
            if (ring.at<std::uint8_t>(r, c) == 0) continue;
            const int l = filled.at<int>(r, c);
            if (l != id && l != 0) ++votes[l];
          }
        }
        if (votes.empty()) continue;
        const auto best = std::max_element(votes.begin(), votes.end(),
                                           [](const auto& a, const auto& b2) { return a.second < b2.second; });
        filled.setTo(best->first, piece);
        changed = true;
      }
    }
    if (!changed) break;
  }
  for (std::size_t i = 0; i < names.size(); ++i) {
    cv::Mat mask = filled == static_cast<int>(i + 1);
    ZoneDef z;
    z.name = names[i].first;
    z.kind = names[i].second;
    z.floor = 0;
    z.polygon = MaskToRing(mask, res);
    if (z.polygon.size() < 3) continue;
    b.zones.push_back(std::move(z));
  }
  b.floors.push_back(std::move(floor));
  FinishZones(&b);
  // Start in the roomiest corridor (or zone).
  double best = -1.0;
  for (std::size_t i = 0; i < b.zones.size(); ++i) {
    const double score = b.zones[i].clearance_m + (b.zones[i].kind == "corridor" ? 100.0 : 0.0);
    if (score > best) {
      best = score;
      b.start_zone = static_cast<int>(i);
    }
  }
  return b;
}

}  // namespace zm::sim
