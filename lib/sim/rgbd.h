// Dense keyframes of the simulator (docs/sim.md, "Dense keyframes"): the colour and depth images
// a keyframe's camera sees, rendered from the floor plan in one pass, compressed the way RTAB-Map
// stores them (JPEG colour, RVL depth: lib/mapdb/dense_codec.h), and packed with the keyframe's
// features into a payload whose 3-D points come from that depth when it is loaded.
//
// Rendering is 2.5-D, like the observation model: per image column one ray is cast on the grid;
// each row then sees the wall (furniture counts as a full-height wall, as for occlusion), the
// floor or the ceiling. Colour: walls take a pastel per 1.6 m block of wall, shaded by the face
// the ray hit and by distance, with a skirting band, a hand rail at 0.9 m and panel seams every
// 1.2 m; furniture is wood, white or blue-grey; the floor has 0.6 m tiles, the ceiling 1.2 m
// panels and lights; each visible landmark is a small spot whose colour its descriptor picks;
// sensor noise is +-4 grey levels. Depth is in millimetres with range-dependent noise (uniform,
// sigma from DenseOptions), 0 beyond the range.
//
// Invariants: the same inputs and seed give the same bytes (the noise is a hash of the seed and
// the pixel); the image keeps the keypoint camera's field of view at any resolution.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "localization/orb_extractor.h"
#include "mapdb/rvl.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/rng.h"

namespace zm::sim {

// How surfaces look. kFlat: pastel blocks of wall and a coloured spot per visible landmark, the
// look every figure of the README was measured with so far. kTextured (appearance.h): surfaces
// textured from world coordinates and a décor seed with repeated décor, no landmark in the
// image: what a feature detector needs (issue 26 §1).
enum class SurfaceStyle : std::uint8_t { kFlat, kTextured };

// The camera's exposure for one image: colour = gain * scene + offset (grey levels), then a
// horizontal box blur of blur_px pixels (motion blur of a turning camera; < 1.5 px: none).
struct FrameLight {
  float gain = 1.0f;
  float offset = 0.0f;
  float blur_px = 0.0f;
};

struct DenseOptions {
  // Resolution at footprint scale 1 (the camera's field of view is kept at any resolution).
  std::uint32_t width = 640;
  std::uint32_t height = 480;
  double range_m = 10.0;         // depth beyond this is 0 (no return)
  // Depth noise, sigma(z) = a + b z + c z^2 metres (uniform with that sigma). The default is a
  // time-of-flight-like 1.5 mm + 3 mm/m (16.5 mm at 5 m; Azure Kinect DK states <= 17 mm): the
  // structured-light 1.5 mm + 2.5 mm/m^2 made far points too noisy for PnP (docs/sim.md).
  double depth_sigma_m = 0.0015;
  double depth_sigma_per_m = 0.003;
  double depth_sigma_per_m2 = 0.0;
  int jpeg_quality = 95;         // OpenCV's default, what RTAB-Map's cv::imencode(".jpg") uses
  // Decimation of the resident point cloud (0 = none): the footprint's calibration knob (5 puts
  // the default scenario's keyframes at 2.0-2.2 MB, docs/sim.md).
  std::uint32_t cloud_step = 5;
  // (0, 1]: the resident footprint scales by this (the resolution by about its square root),
  // for experiments at a fraction of the device (--device-scale).
  double footprint_scale = 1.0;
  SurfaceStyle style = SurfaceStyle::kFlat;
  std::uint64_t decor_seed = 1;  // kTextured: the building's décor (same seed, same look)
  // kTextured: posters and signs from small catalogues, so places look alike (aliasing); false
  // makes every one unique (`zonemap sim --decor unique`, the robustness table's control).
  bool repeated_decor = true;
};

// Checks ranges; errors name the option ("--dense", "--cloud-step", ...).
[[nodiscard]] Status ValidateDenseOptions(const DenseOptions& options);

struct RgbdImage {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3, row-major
  DepthImage16 depth;
};

// Renders colour and depth seen from body pose `t_map_body` on `floor` at width x height. kFlat
// draws the visible landmarks (LandmarkMap::Visible from the same pose) as spots; kTextured
// ignores `visible` (pass an empty span) and applies `light`.
void RenderRgbd(const Building& building, int floor, const Pose3& t_map_body,
                const CameraModel& camera, const LandmarkMap& landmarks,
                std::span<const VisibleLandmark> visible, std::uint32_t width, std::uint32_t height,
                const DenseOptions& dense, std::uint64_t seed, RgbdImage* out,
                const FrameLight& light = {});

struct RenderedKeyframe {
  std::vector<std::byte> payload;  // EncodePayload blob (kJpegColourRvlDepth, points from depth)
  FeatureSet features;             // its features (points empty: they come from the depth)
  std::uint32_t jpeg_bytes = 0;
  std::uint32_t rvl_bytes = 0;
  std::uint32_t resident_bytes = 0;  // slot bytes once decoded
};

// One keyframe: features (MakeFeatures, drawing from `rng`) and its RGB-D image at
// width x height (noise seeded from `rng`), encoded into a dense payload for keyframe `id`.
[[nodiscard]] Status RenderKeyframe(const Building& building, const LandmarkMap& landmarks, int floor,
                                    const Pose3& t_map_body, const CameraModel& camera,
                                    const NoiseOptions& noise, const DenseOptions& dense,
                                    std::uint32_t width, std::uint32_t height, KeyframeId id,
                                    Rng& rng, RenderedKeyframe* out);

// Issue 26: a keyframe whose features come from its own pixels. Renders the textured image at
// width x height (gain 1: the mapping run's exposure), extracts ORB with `extractor` (made for
// that image size: ScaledIntrinsics of the keypoint camera), keeps the keypoints in the keypoint
// camera's pixels, and encodes the dense payload like RenderKeyframe (points from the depth on
// load). Nothing of a landmark is used.
[[nodiscard]] Status RenderKeyframeFromPixels(const Building& building, int floor,
                                              const Pose3& t_map_body, const CameraModel& camera,
                                              const DenseOptions& dense, std::uint32_t width,
                                              std::uint32_t height, KeyframeId id,
                                              std::uint64_t image_seed, OrbExtractor& extractor,
                                              RenderedKeyframe* out);

}  // namespace zm::sim
