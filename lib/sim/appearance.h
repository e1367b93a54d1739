// The look of the simulated building's surfaces (issue 26 §1): what a feature detector sees.
//
// Every colour is a function of WORLD coordinates on a surface (a wall's position along its face
// and height, a floor's or ceiling's x, y) and of a décor seed, never of the camera, the frame or
// any landmark: a spot of wall looks the same from every viewpoint, in the mapping run and in the
// localization run, which is what makes features repeatable; and nothing in an image can carry a
// landmark's identity or descriptor.
//
// What a surface carries (docs/sim.md, "Textured rendering"):
//   walls      a pastel per 1.6 m block of wall and one of four finishes per block: plaster
//              (low-contrast value noise), tiles below 1.2 m (0.2 m, grout lines), wood boards
//              below 1.0 m, patterned wallpaper; skirting, hand rail, panel seams every 1.2 m;
//              dark door frames where a wall ends at an opening; posters (0.7 x 0.8 m) on a
//              2.4 m grid and signs (1.0 x 0.25 m) on a 6 m grid, each drawn from a catalogue of
//              kPosterDesigns / kSignDesigns designs;
//   furniture  wood grain, a darker top edge, drawer lines with handles;
//   floor      0.6 m tiles with per-tile shade and a faint vinyl speckle (3 cm);
//   ceiling    1.2 m panels, every fourth a light.
//
// Repeated décor, as in a real hospital: the catalogues are small and a design is picked by a
// hash of its wall slot, so the same poster and the same sign appear in many places, and
// blocks share finishes and palettes. Different places therefore look alike (aliasing), and
// appearance alone cannot always tell them apart: geometric verification must.
#pragma once

#include <array>
#include <cstdint>

namespace zm::sim {

using Rgb = std::array<float, 3>;

inline constexpr std::uint32_t kPosterDesigns = 8;
inline constexpr std::uint32_t kSignDesigns = 6;

// The base colours both rendering styles share: the flat style paints them as they are, the
// textured one (SurfaceLook) draws its finishes over them.
inline constexpr Rgb kWallPalette[] = {{205, 222, 200}, {232, 226, 205}, {200, 215, 230},
                                       {238, 238, 232}, {236, 228, 190}, {215, 215, 215}};
inline constexpr Rgb kFloor = {170, 168, 160};
inline constexpr Rgb kCeiling = {232, 232, 226};

// Floor and fractional part without SSE4.1's roundss: the builds target baseline x86-64 and
// ARMv8-A, and the renderer calls these for every pixel.
inline float FloorF(float v) {
  const auto i = static_cast<float>(static_cast<std::int64_t>(v));
  return i > v ? i - 1.0f : i;
}
inline float Frac(float v) { return v - FloorF(v); }

// One wall column as the ray cast found it.
struct WallSurface {
  float along_m = 0.0f;       // coordinate along the face (map x or y), metres
  std::uint64_t face_key = 0;  // the face's line: axis, grid line and side (FaceKey)
  std::uint64_t block_key = 0;  // the 1.6 m block of wall (palette and finish)
  float end_m = 1e9f;         // distance along the face to where the wall ends at free space
  bool furniture = false;
};

// The key of a wall face: which axis it is perpendicular to, its grid line and which side the
// camera looks at it from; the same for every column and every frame that sees this face.
[[nodiscard]] std::uint64_t FaceKey(bool x_face, int line, bool from_positive_side, int floor);
[[nodiscard]] std::uint64_t BlockKey(int col, int row, bool furniture, int floor);

// SplitMix64's finaliser: the one hash of the renderer (deterministic on every platform).
[[nodiscard]] std::uint64_t Mix64(std::uint64_t x);

class SurfaceLook {
 public:
  // decor_seed: the building's décor; the same seed gives the same building look.
  // repeated_decor: posters and signs from the small catalogues (the hospital's aliasing); false
  // gives every poster and sign slot a design of its own, to measure what aliasing costs.
  explicit SurfaceLook(std::uint64_t decor_seed, bool repeated_decor = true)
      : seed_(decor_seed), repeated_(repeated_decor) {}

  // Colours before distance shading, lighting and sensor noise (0..255 per channel).
  [[nodiscard]] Rgb Wall(const WallSurface& wall, float height_m) const;
  [[nodiscard]] Rgb Floor(float x_m, float y_m) const;
  [[nodiscard]] Rgb Ceiling(float x_m, float y_m) const;

 private:
  [[nodiscard]] Rgb Furniture(const WallSurface& wall, float height_m) const;
  [[nodiscard]] float ValueNoise(float x, float y, std::uint64_t salt) const;

  std::uint64_t seed_;
  bool repeated_;
};

}  // namespace zm::sim
