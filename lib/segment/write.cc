// The write stage (write.h). OpenCV exceptions become Status values here.
#include "segment/write.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "zones/polygon.h"

namespace zm {

Status CheckOutlineOptions(const OutlineOptions& o) {
  if (o.simplify_tolerance_m < 0.0) {
    return InvalidArgument("segmentation option simplify_tolerance_m must be >= 0");
  }
  return Status::Ok();
}

namespace {

// Each label's bounding box (empty for a label no cell has), labels 1..max_label, in one pass.
std::vector<cv::Rect> LabelBoxes(const cv::Mat& labels, int max_label) {
  const auto n = static_cast<std::size_t>(std::max(0, max_label)) + 1;
  std::vector<int> r0(n, labels.rows), r1(n, -1), c0(n, labels.cols), c1(n, -1);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] <= 0 || l[c] > max_label) continue;
      const auto i = static_cast<std::size_t>(l[c]);
      r0[i] = std::min(r0[i], r), r1[i] = std::max(r1[i], r);
      c0[i] = std::min(c0[i], c), c1[i] = std::max(c1[i], c);
    }
  }
  std::vector<cv::Rect> boxes(n);
  for (std::size_t i = 1; i < n; ++i) {
    if (r1[i] >= 0) boxes[i] = cv::Rect(c0[i], r0[i], c1[i] - c0[i] + 1, r1[i] - r0[i] + 1);
  }
  return boxes;
}

}  // namespace

Result<std::vector<Zone>> SegmentationToZones(const Segmentation& seg, const OccupancyGrid& grid,
                                              const OutlineOptions& options) {
  std::vector<Zone> zones;
  std::map<std::string, int> per_kind;
  const double eps_px = options.simplify_tolerance_m / grid.resolution_m;
  try {
    // Each outline is traced inside its segment's box with a cell of margin, not over the whole
    // grid once per segment: findContours walks the same cells (the box is all the mask holds)
    // and its offset puts them back in grid cells.
    int max_label = 0;
    for (const SegmentInfo& s : seg.segments) max_label = std::max(max_label, s.label);
    const std::vector<cv::Rect> boxes = LabelBoxes(seg.labels, max_label);
    const cv::Rect whole(0, 0, seg.labels.cols, seg.labels.rows);
    for (const SegmentInfo& s : seg.segments) {
      const cv::Rect cells = s.label > 0 ? boxes[static_cast<std::size_t>(s.label)] : whole;
      if (cells.empty()) continue;  // no cell: no contour
      const cv::Rect box =
          cv::Rect(cells.x - 1, cells.y - 1, cells.width + 2, cells.height + 2) & whole;
      cv::Mat mask = seg.labels(box) == s.label;
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, box.tl());
      if (contours.empty()) continue;
      const auto largest = std::max_element(
          contours.begin(), contours.end(),
          [](const auto& a, const auto& b) { return cv::contourArea(a) < cv::contourArea(b); });
      std::vector<Eigen::Vector2d> ring;
      // Simplify; halve the tolerance while the outline self-intersects; last resort the hull.
      for (double eps = eps_px;; eps *= 0.5) {
        std::vector<cv::Point> approx;
        if (eps < 0.25) {
          cv::convexHull(*largest, approx);
        } else {
          cv::approxPolyDP(*largest, approx, eps, true);
        }
        ring.clear();
        for (const cv::Point& p : approx) ring.push_back(grid.CellToMetres(p.x, p.y));
        if (eps < 0.25 ||
            (ring.size() >= 3 && !FindSelfIntersection(ring) && std::abs(SignedArea(ring)) > 0.0)) {
          break;
        }
      }
      if (ring.size() < 3 || std::abs(SignedArea(ring)) <= 0.0) continue;
      if (SignedArea(ring) < 0.0) std::reverse(ring.begin(), ring.end());  // GeoJSON: CCW
      Zone z;
      z.id = ZoneId{static_cast<std::int32_t>(zones.size())};
      z.name = s.kind + "_" + std::to_string(++per_kind[s.kind]);
      z.kind = s.kind;
      z.floor = 0;
      const ZRange band = FloorZRange(z.floor);
      z.z_min_m = band.min_m;
      z.z_max_m = band.max_m;
      z.polygon = std::move(ring);
      zones.push_back(std::move(z));
    }
  } catch (const cv::Exception& e) {
    return Internal(std::string("zone polygons: OpenCV failed: ") + e.what());
  }
  return zones;
}

Status WriteSegmentationPng(const std::string& path, const OccupancyGrid& grid,
                            const Segmentation& seg) {
  if (seg.labels.size() != grid.cells.size()) {
    return InvalidArgument("segmentation and grid differ in size");
  }
  cv::Mat img(grid.cells.size(), CV_8UC3);
  for (int r = 0; r < img.rows; ++r) {
    const std::uint8_t* g = grid.cells.ptr<std::uint8_t>(r);
    const int* l = seg.labels.ptr<int>(r);
    auto* out = img.ptr<cv::Vec3b>(r);
    for (int c = 0; c < img.cols; ++c) {
      if (l[c] > 0) {
        // A fixed hash of the label: neighbours get unrelated, reproducible colours.
        const auto h = static_cast<std::uint32_t>(l[c]) * 2654435761u;
        out[c] = cv::Vec3b(static_cast<std::uint8_t>(64 + (h >> 8) % 192),
                           static_cast<std::uint8_t>(64 + (h >> 16) % 192),
                           static_cast<std::uint8_t>(64 + (h >> 24) % 192));
      } else {
        const std::uint8_t v = g[c] == kCellOccupied ? 0 : (g[c] == kCellFree ? 255 : 160);
        out[c] = cv::Vec3b(v, v, v);
      }
    }
  }
  try {
    if (!cv::imwrite(path, img)) return IoError(path + ": cannot write the PNG");
  } catch (const cv::Exception& e) {
    return IoError(path + ": OpenCV could not write it: " + e.what());
  }
  return Status::Ok();
}

}  // namespace zm
