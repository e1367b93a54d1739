// Depth rendering and PNG encoding (see depth.h).
#include "sim/depth.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace zm::sim {

Status RenderDepthPng(const Building& building, int floor, const Pose3& t_map_body,
                      const CameraModel& camera, const DepthOptions& options, Rng& rng,
                      std::vector<std::byte>* png) {
  if (options.width < 8 || options.height < 8 || options.width > 4096 || options.height > 4096) {
    return InvalidArgument("dense resolution " + std::to_string(options.width) + "x" +
                           std::to_string(options.height) + " is outside [8, 4096] pixels");
  }
  const FloorMap& fl = building.floors[static_cast<std::size_t>(floor)];
  const CameraIntrinsics& k = camera.intrinsics;
  const double sx = static_cast<double>(options.width) / k.width;
  const double sy = static_cast<double>(options.height) / k.height;
  const double fx = k.fx * sx, fy = k.fy * sy, cx = k.cx * sx, cy = k.cy * sy;
  const Eigen::Vector2d eye = t_map_body.translation().head<2>();
  const double yaw = Yaw(t_map_body);
  const double cam_h = t_map_body.translation().z() - fl.z_m;  // above this floor
  const double ceil_h = building.wall_height_m;
  const double range = options.range_m;

  cv::Mat depth(static_cast<int>(options.height), static_cast<int>(options.width), CV_16UC1);
  std::vector<double> wall_z(options.width);
  for (std::uint32_t u = 0; u < options.width; ++u) {
    const double xn = (u + 0.5 - cx) / fx;  // camera x / z
    // Camera x is body -y: the ray's bearing in the body frame is atan2(-xn, 1).
    const double a = yaw + std::atan2(-xn, 1.0);
    const double d = CastRay(fl.grid, eye, Eigen::Vector2d(std::cos(a), std::sin(a)), range * 1.5);
    wall_z[u] = d / std::sqrt(1.0 + xn * xn);
  }
  for (int v = 0; v < depth.rows; ++v) {
    const double yn = (v + 0.5 - cy) / fy;  // camera y / z, y down
    double plane_z = 1e9;
    if (yn > 1e-9) plane_z = cam_h / yn;               // floor
    if (yn < -1e-9) plane_z = (ceil_h - cam_h) / -yn;  // ceiling
    auto* row = depth.ptr<std::uint16_t>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const double z = std::min(wall_z[static_cast<std::size_t>(u)], plane_z);
      if (!(z > 0.0) || z > range) {
        row[u] = 0;
        continue;
      }
      const double sigma = 0.0015 + 0.0025 * z * z;
      // Uniform noise with that sigma (cheaper than Gaussian, same effect on compression).
      const double noisy = z + sigma * 3.4641016 * (rng.Uniform() - 0.5);
      row[u] = static_cast<std::uint16_t>(std::clamp(std::lround(noisy * 1000.0), 1L,
                                                     std::lround(range * 1000.0)));
    }
  }
  std::vector<std::uint8_t> buf;
  try {
    if (!cv::imencode(".png", depth, buf, {cv::IMWRITE_PNG_COMPRESSION, options.png_compression})) {
      return Internal("PNG encoding of a depth image failed");
    }
  } catch (const cv::Exception& e) {
    return Internal(std::string("PNG encoding of a depth image failed: ") + e.what());
  }
  png->resize(buf.size());
  std::memcpy(png->data(), buf.data(), buf.size());
  return Status::Ok();
}

}  // namespace zm::sim
