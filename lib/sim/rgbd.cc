// RGB-D rendering and dense keyframe payloads (see rgbd.h). The per-pixel loop is in float and
// draws its noise from a hash, so a 640x480 keyframe renders in a few milliseconds.
#include "sim/rgbd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include <memory>
#include <opencv2/imgproc.hpp>

#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "sim/appearance.h"

namespace zm::sim {
namespace {

constexpr Rgb kFurniturePalette[] = {{150, 110, 70}, {225, 225, 220}, {160, 185, 210}};
constexpr Rgb kFar = {60, 60, 64};  // nothing within the cast range

std::uint8_t ToByte(float v) { return static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f)); }

struct Column {
  float z = 0.0f;       // wall depth along the optical axis (inf when nothing was hit)
  Rgb base{};           // wall colour with the face shading
  float along_m = 0.0f; // coordinate along the wall (panel seams)
  bool furniture = false;
  float face = 1.0f;    // face shading (kTextured applies it per pixel)
  WallSurface surface;  // kTextured
};

// Distance along the face from the hit point to where the wall ends at free space (a doorway
// or a corridor's mouth), looking one cell each way along the face; far when it goes on.
float WallEnd(const SimGrid& grid, const RayHit& hit, const Eigen::Vector2d& p) {
  const double res = grid.resolution_m;
  float end = 1e9f;
  if (hit.x_face) {  // the face runs along y
    const double lo = grid.origin_m.y() + hit.row * res;
    if (grid.Free(hit.col, hit.row - 1)) end = std::min(end, static_cast<float>(p.y() - lo));
    if (grid.Free(hit.col, hit.row + 1)) end = std::min(end, static_cast<float>(lo + res - p.y()));
  } else {
    const double lo = grid.origin_m.x() + hit.col * res;
    if (grid.Free(hit.col - 1, hit.row)) end = std::min(end, static_cast<float>(p.x() - lo));
    if (grid.Free(hit.col + 1, hit.row)) end = std::min(end, static_cast<float>(lo + res - p.x()));
  }
  return end;
}

// Horizontal box blur of `px` pixels over each row of an RGB image, in place, with one row of
// scratch: the smear of a camera turning during its exposure.
void BlurRows(std::uint8_t* rgb, std::uint32_t width, std::uint32_t height, float px,
              std::vector<std::uint8_t>* row) {
  const int half = static_cast<int>(px * 0.5f);
  if (half < 1) return;
  const int w = static_cast<int>(width);
  row->resize(std::size_t{width} * 3);
  for (std::uint32_t v = 0; v < height; ++v) {
    std::uint8_t* r = rgb + std::size_t{v} * width * 3;
    std::copy(r, r + std::size_t{width} * 3, row->begin());
    for (int ch = 0; ch < 3; ++ch) {
      int sum = 0;
      for (int u = -half; u <= half; ++u) sum += (*row)[3 * static_cast<std::size_t>(std::clamp(u, 0, w - 1)) + static_cast<std::size_t>(ch)];
      const int n = 2 * half + 1;
      for (int u = 0; u < w; ++u) {
        r[3 * u + ch] = static_cast<std::uint8_t>(sum / n);
        sum += (*row)[3 * static_cast<std::size_t>(std::min(u + half + 1, w - 1)) + static_cast<std::size_t>(ch)] -
               (*row)[3 * static_cast<std::size_t>(std::max(u - half, 0)) + static_cast<std::size_t>(ch)];
      }
    }
  }
}

}  // namespace

Status ValidateDenseOptions(const DenseOptions& o) {
  if (o.width < 8 || o.height < 8 || o.width > kMaxDenseSide || o.height > kMaxDenseSide) {
    return InvalidArgument("--dense " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                           " is outside [8, " + std::to_string(kMaxDenseSide) + "] pixels");
  }
  if (o.cloud_step > kMaxCloudStep) {
    return InvalidArgument("--cloud-step " + std::to_string(o.cloud_step) + " is outside [0, " +
                           std::to_string(kMaxCloudStep) + "]");
  }
  if (o.jpeg_quality < 1 || o.jpeg_quality > 100) {
    return InvalidArgument("--jpeg-quality " + std::to_string(o.jpeg_quality) + " is outside [1, 100]");
  }
  if (!(o.footprint_scale > 0.0 && o.footprint_scale <= 1.0)) {
    return InvalidArgument("--footprint-scale " + std::to_string(o.footprint_scale) + " is outside (0, 1]");
  }
  if (!(o.range_m > 0.1 && o.range_m <= 60.0)) {
    return InvalidArgument("dense range " + std::to_string(o.range_m) + " m is outside (0.1, 60]");
  }
  if (!(o.depth_sigma_m >= 0.0 && o.depth_sigma_per_m >= 0.0 && o.depth_sigma_per_m2 >= 0.0)) {
    return InvalidArgument("--depth-noise coefficients must be >= 0");
  }
  return Status::Ok();
}

void RenderRgbd(const Building& building, int floor, const Pose3& t_map_body,
                const CameraModel& camera, const LandmarkMap& landmarks,
                std::span<const VisibleLandmark> visible, std::uint32_t width, std::uint32_t height,
                const DenseOptions& dense, std::uint64_t seed, RgbdImage* out,
                const FrameLight& light) {
  const bool textured = dense.style == SurfaceStyle::kTextured;
  const SurfaceLook look(dense.decor_seed, dense.repeated_decor);
  const double range_m = dense.range_m;
  const auto sigma_a = static_cast<float>(dense.depth_sigma_m);
  const auto sigma_b = static_cast<float>(dense.depth_sigma_per_m);
  const auto sigma_c = static_cast<float>(dense.depth_sigma_per_m2);
  const FloorMap& fl = building.floors[static_cast<std::size_t>(floor)];
  const SimGrid& grid = fl.grid;
  const CameraIntrinsics& k = camera.intrinsics;
  const double sx = static_cast<double>(width) / k.width;
  const double sy = static_cast<double>(height) / k.height;
  const double fx = k.fx * sx, fy = k.fy * sy, cx = k.cx * sx, cy = k.cy * sy;
  const Eigen::Vector2d eye = t_map_body.translation().head<2>();
  const double yaw = Yaw(t_map_body);
  // Camera axes on the floor plane: forward, and right (camera x = -body y).
  const Eigen::Vector2d fwd(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d right(std::sin(yaw), -std::cos(yaw));
  const auto cam_h = static_cast<float>(t_map_body.translation().z() - fl.z_m);
  const auto ceil_h = static_cast<float>(building.wall_height_m);
  const auto furniture_h = static_cast<float>(building.furniture_height_m);
  const auto range = static_cast<float>(range_m);
  const float range_mm = range * 1000.0f;

  out->width = width;
  out->height = height;
  out->rgb.resize(std::size_t{width} * height * 3);
  out->depth.width = width;
  out->depth.height = height;
  out->depth.pixels.resize(std::size_t{width} * height);

  std::vector<Column> cols(width);
  std::vector<float> xn_of(width);
  const double cast_range = range_m * 1.5;
  for (std::uint32_t u = 0; u < width; ++u) {
    const double xn = (u + 0.5 - cx) / fx;  // camera x / z
    xn_of[u] = static_cast<float>(xn);
    const double norm = std::sqrt(1.0 + xn * xn);
    const Eigen::Vector2d dir = (fwd + xn * right) / norm;
    const RayHit hit = CastRayHit(grid, eye, dir, cast_range);
    Column& c = cols[u];
    if (!hit.hit) {
      c.z = std::numeric_limits<float>::infinity();
      continue;
    }
    c.z = static_cast<float>(hit.distance_m / norm);
    const Eigen::Vector2d p = eye + hit.distance_m * dir;
    c.along_m = static_cast<float>(hit.x_face ? p.y() : p.x());
    c.furniture = grid.InBounds(hit.col, hit.row) && fl.furniture[grid.Index(hit.col, hit.row)] != 0;
    if (textured) {
      const int line = hit.x_face ? hit.col : hit.row;
      const bool positive = hit.x_face ? dir.x() < 0.0 : dir.y() < 0.0;  // seen from +x / +y
      c.surface.along_m = c.along_m;
      c.surface.face_key = FaceKey(hit.x_face, line, positive, floor);
      c.surface.block_key = BlockKey(hit.col, hit.row, c.furniture, floor);
      c.surface.end_m = c.furniture ? 1e9f : WallEnd(grid, hit, p);
      c.surface.furniture = c.furniture;
      c.face = hit.x_face ? 0.82f : 1.0f;
      continue;
    }
    const std::uint64_t block =
        Mix64((static_cast<std::uint64_t>(static_cast<std::uint32_t>(hit.col >> (c.furniture ? 3 : 5))) << 32) ^
            static_cast<std::uint32_t>(hit.row >> (c.furniture ? 3 : 5)) ^
            (static_cast<std::uint64_t>(floor) << 58));
    c.base = c.furniture ? kFurniturePalette[block % std::size(kFurniturePalette)]
                         : kWallPalette[block % std::size(kWallPalette)];
    const float face = hit.x_face ? 0.82f : 1.0f;
    for (float& ch : c.base) ch *= face;
  }

  const float ex = static_cast<float>(eye.x()), ey = static_cast<float>(eye.y());
  const float fxw = static_cast<float>(fwd.x()), fyw = static_cast<float>(fwd.y());
  const float rxw = static_cast<float>(right.x()), ryw = static_cast<float>(right.y());
  // Per-column wall colour with distance shading, so a wall pixel only applies its bands.
  // (kTextured keeps only the distance shading, in channel 0: the colour is per pixel.)
  std::vector<Rgb> wall_rgb(width);
  for (std::uint32_t u = 0; u < width; ++u) {
    const float shade = std::isfinite(cols[u].z) ? 1.0f / (1.0f + 0.08f * cols[u].z) : 1.0f;
    wall_rgb[u] = textured ? Rgb{shade, shade, shade}
                           : Rgb{cols[u].base[0] * shade, cols[u].base[1] * shade, cols[u].base[2] * shade};
  }
  // Sensor noise in grey levels, uniform over -4..4 (both halves of the table sum to 0).
  static constexpr float kNoise[16] = {-4, -3, -2, -1, 0, 1, 2, 3, 4, -3, -2, -1, 0, 1, 2, 3};
  std::uint8_t* rgb = out->rgb.data();
  std::uint16_t* depth = out->depth.pixels.data();
  for (std::uint32_t v = 0; v < height; ++v) {
    const auto yn = static_cast<float>((v + 0.5 - cy) / fy);  // camera y / z, y down
    float plane_z = std::numeric_limits<float>::infinity();
    bool is_floor = false;
    if (yn > 1e-6f) {
      plane_z = cam_h / yn;
      is_floor = true;
    } else if (yn < -1e-6f) {
      plane_z = (ceil_h - cam_h) / -yn;
    }
    // The floor / ceiling point of column u is (ax + bx * xn, ay + by * xn), in tile units.
    const float tile = is_floor ? 1.0f / 0.6f : 1.0f / 1.2f;
    const float ax = (ex + plane_z * fxw) * tile, bx = plane_z * rxw * tile;
    const float ay = (ey + plane_z * fyw) * tile, by = plane_z * ryw * tile;
    const float plane_shade = 1.0f / (1.0f + 0.08f * plane_z);
    const float seam = is_floor ? 0.03f : 0.02f;
    // A xorshift64* stream per row: one multiply a pixel.
    std::uint64_t state = Mix64(seed ^ (std::uint64_t{v} * 0xD1B54A32D192ED03ULL)) | 1u;
    std::uint8_t* rgb_row = rgb + std::size_t{v} * width * 3;
    std::uint16_t* depth_row = depth + std::size_t{v} * width;
    for (std::uint32_t u = 0; u < width; ++u) {
      state ^= state >> 12;
      state ^= state << 25;
      state ^= state >> 27;
      const std::uint64_t h = state * 0x2545F4914F6CDD1DULL;
      const Column& col = cols[u];
      float z;
      Rgb c;
      if (textured) {
        if (col.z <= plane_z) {
          z = col.z;
          if (!std::isfinite(z)) {
            c = kFar;
          } else {
            const Rgb wall = look.Wall(col.surface, cam_h - yn * z);
            const float shade = col.face * wall_rgb[u][0];  // distance shading (see above)
            c = {wall[0] * shade, wall[1] * shade, wall[2] * shade};
          }
        } else {
          z = plane_z;
          const float wx = ex + plane_z * (fxw + rxw * xn_of[u]);
          const float wy = ey + plane_z * (fyw + ryw * xn_of[u]);
          const Rgb surf = is_floor ? look.Floor(wx, wy) : look.Ceiling(wx, wy);
          c = {surf[0] * plane_shade, surf[1] * plane_shade, surf[2] * plane_shade};
        }
        for (float& ch : c) ch = ch * light.gain + light.offset;
      } else if (col.z <= plane_z) {
        z = col.z;
        if (!std::isfinite(z)) {
          c = kFar;
        } else {
          const float height_m = cam_h - yn * z;  // above this floor
          float shade = height_m < 0.12f ? 0.55f : 1.0f;  // skirting
          if (col.furniture) {
            if (std::abs(height_m - furniture_h) < 0.03f) shade *= 0.7f;
          } else {
            if (height_m > 0.86f && height_m < 0.94f) shade *= 0.75f;  // hand rail
            if (Frac(col.along_m * (1.0f / 1.2f)) < 0.015f) shade *= 0.8f;  // panel seam
          }
          c = {wall_rgb[u][0] * shade, wall_rgb[u][1] * shade, wall_rgb[u][2] * shade};
        }
      } else {
        z = plane_z;
        const float tx = ax + bx * xn_of[u], ty = ay + by * xn_of[u];
        const float fx_t = FloorF(tx), fy_t = FloorF(ty);
        float shade = plane_shade;
        if (tx - fx_t < seam || ty - fy_t < seam) shade *= is_floor ? 0.8f : 0.85f;
        const int parity = static_cast<int>(fx_t) + (is_floor ? 1 : 3) * static_cast<int>(fy_t);
        if (is_floor) {
          if ((parity & 1) != 0) shade *= 0.93f;
          c = {kFloor[0] * shade, kFloor[1] * shade, kFloor[2] * shade};
        } else if ((parity & 3) == 0) {
          c = {255.0f, 255.0f, 250.0f};  // a light panel
        } else {
          c = {kCeiling[0] * shade, kCeiling[1] * shade, kCeiling[2] * shade};
        }
      }
      rgb_row[3 * u] = ToByte(c[0] + kNoise[h & 15u]);
      rgb_row[3 * u + 1] = ToByte(c[1] + kNoise[(h >> 4) & 15u]);
      rgb_row[3 * u + 2] = ToByte(c[2] + kNoise[(h >> 8) & 15u]);
      if (!(z > 0.0f) || z > range) {
        depth_row[u] = 0;
        continue;
      }
      const float sigma = sigma_a + (sigma_b + sigma_c * z) * z;
      const float u01 = static_cast<float>(h >> 40) * 0x1.0p-24f;
      const float mm = (z + sigma * 3.4641016f * (u01 - 0.5f)) * 1000.0f;
      depth_row[u] = static_cast<std::uint16_t>(std::clamp(mm + 0.5f, 1.0f, range_mm));
    }
  }

  if (textured) {
    // Nothing of a landmark is drawn: the image is the building's alone.
    thread_local std::vector<std::uint8_t> blur_row;
    if (light.blur_px >= 1.5f) BlurRows(rgb, width, height, light.blur_px, &blur_row);
    return;
  }
  // Landmarks as spots (they are what the features describe): radius 1.6 px at 640 wide.
  const auto& lms = landmarks.landmarks();
  const double radius = std::max(1.0, 1.6 * sx);
  const int reach = static_cast<int>(std::ceil(radius));
  for (const VisibleLandmark& vis : visible) {
    const Descriptor256& d = lms[vis.landmark].descriptor;
    const float dark = (d[3] & 1u) != 0 ? 0.35f : 1.0f;
    const Rgb spot = {d[0] * dark, d[1] * dark, d[2] * dark};
    const double pu = vis.uv.x() * sx, pv = vis.uv.y() * sy;
    const int u0 = static_cast<int>(std::floor(pu)), v0 = static_cast<int>(std::floor(pv));
    for (int dv = -reach; dv <= reach; ++dv) {
      for (int du = -reach; du <= reach; ++du) {
        const int u = u0 + du, v = v0 + dv;
        if (u < 0 || v < 0 || u >= static_cast<int>(width) || v >= static_cast<int>(height)) continue;
        const double ddx = u + 0.5 - pu, ddy = v + 0.5 - pv;
        if (ddx * ddx + ddy * ddy > radius * radius) continue;
        std::uint8_t* px = rgb + 3 * (static_cast<std::size_t>(v) * width + static_cast<std::size_t>(u));
        for (std::size_t ch = 0; ch < 3; ++ch) px[ch] = ToByte(0.3f * px[ch] + 0.7f * spot[ch]);
      }
    }
  }
}

namespace {

// The dense payload of a keyframe whose features are in out->features.
Status EncodeRenderedKeyframe(const RgbdImage& img, const DenseOptions& dense, std::uint32_t width,
                              std::uint32_t height, KeyframeId id, RenderedKeyframe* out) {
  ZM_ASSIGN_OR_RETURN(DenseKeyframePayload p,
                      EncodeDenseKeyframe(id, out->features.descriptors, out->features.keypoints,
                                          {.rgb = img.rgb,
                                           .depth = &img.depth,
                                           .width = width,
                                           .height = height,
                                           .jpeg_quality = dense.jpeg_quality,
                                           .cloud_step = dense.cloud_step}));
  out->payload = std::move(p.payload);
  out->jpeg_bytes = p.jpeg_bytes;
  out->rvl_bytes = p.rvl_bytes;
  out->resident_bytes = p.resident_bytes;
  return Status::Ok();
}

}  // namespace

Status RenderKeyframe(const Building& building, const LandmarkMap& landmarks, int floor,
                      const Pose3& t_map_body, const CameraModel& camera, const NoiseOptions& noise,
                      const DenseOptions& dense, std::uint32_t width, std::uint32_t height,
                      KeyframeId id, Rng& rng, RenderedKeyframe* out) {
  std::vector<VisibleLandmark> visible;
  landmarks.Visible(building, floor, t_map_body, camera, &visible);
  MakeFeatures(landmarks, visible, t_map_body, camera, noise, /*with_points=*/false, rng, &out->features);
  const std::uint64_t image_seed = rng.Next();
  // One image buffer per worker thread, reused: no page faults and no zero-fill per keyframe.
  thread_local RgbdImage img;
  RenderRgbd(building, floor, t_map_body, camera, landmarks, visible, width, height, dense, image_seed,
             &img);
  return EncodeRenderedKeyframe(img, dense, width, height, id, out);
}

Status RenderKeyframeFromPixels(const Building& building, int floor, const Pose3& t_map_body,
                                const CameraModel& camera, const DenseOptions& dense,
                                std::uint32_t width, std::uint32_t height, KeyframeId id,
                                std::uint64_t image_seed, OrbExtractor& extractor,
                                RenderedKeyframe* out) {
  static const LandmarkMap kNoLandmarks;
  DenseOptions textured = dense;
  textured.style = SurfaceStyle::kTextured;
  thread_local RgbdImage img;
  RenderRgbd(building, floor, t_map_body, camera, kNoLandmarks, {}, width, height, textured,
             image_seed, &img);
  thread_local cv::Mat grey;
  const cv::Mat rgb(static_cast<int>(height), static_cast<int>(width), CV_8UC3, img.rgb.data());
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  thread_local std::unique_ptr<OrbFeatures> features;
  if (!features || features->capacity() < extractor.options().max_features) {
    features = std::make_unique<OrbFeatures>(extractor.options().max_features);
  }
  ZM_RETURN_IF_ERROR(extractor.Extract(grey, {}, features.get()));
  const std::uint32_t n = features->count;
  const float to_x = static_cast<float>(camera.intrinsics.width) / static_cast<float>(width);
  const float to_y = static_cast<float>(camera.intrinsics.height) / static_cast<float>(height);
  out->features.Clear();
  out->features.descriptors.assign(features->descriptors.begin(), features->descriptors.begin() + n);
  out->features.keypoints.resize(2 * std::size_t{n});
  for (std::size_t i = 0; i < n; ++i) {
    out->features.keypoints[2 * i] = features->keypoints[2 * i] * to_x;
    out->features.keypoints[2 * i + 1] = features->keypoints[2 * i + 1] * to_y;
  }
  return EncodeRenderedKeyframe(img, textured, width, height, id, out);
}

}  // namespace zm::sim
