// Surface looks of the simulated building (see appearance.h). Float arithmetic only, a few
// hashes a pixel, no allocation: the renderer calls this for every pixel of every frame.
#include "sim/appearance.h"

#include <cmath>
#include <cstddef>
#include <iterator>

namespace zm::sim {
namespace {

constexpr Rgb kTilePalette[] = {{226, 232, 236}, {200, 222, 214}, {236, 236, 236}};
constexpr Rgb kBoard = {176, 138, 98};
constexpr Rgb kPaperAccent = {150, 170, 190};
constexpr Rgb kFrame = {92, 74, 58};
constexpr Rgb kWood = {150, 110, 70};
constexpr Rgb kWhiteLaminate = {225, 225, 220};
constexpr Rgb kPosterInk[] = {{30, 40, 70},   {200, 60, 50},  {40, 120, 80},
                              {230, 190, 60}, {240, 240, 235}, {90, 90, 100}};

std::int64_t Cell(float v) { return static_cast<std::int64_t>(FloorF(v)); }
Rgb Scale(const Rgb& c, float s) { return {c[0] * s, c[1] * s, c[2] * s}; }

std::uint64_t Key2(std::uint64_t a, std::int64_t b) {
  return Mix64(a ^ (static_cast<std::uint64_t>(b) * 0x9E3779B97F4A7C15ULL));
}

}  // namespace

std::uint64_t Mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

std::uint64_t FaceKey(bool x_face, int line, bool from_positive_side, int floor) {
  return Mix64((static_cast<std::uint64_t>(x_face) << 62) ^
               (static_cast<std::uint64_t>(from_positive_side) << 61) ^
               (static_cast<std::uint64_t>(static_cast<std::uint32_t>(floor)) << 40) ^
               static_cast<std::uint32_t>(line));
}

std::uint64_t BlockKey(int col, int row, bool furniture, int floor) {
  const int shift = furniture ? 3 : 5;  // 0.4 m pieces of furniture, 1.6 m blocks of wall
  return Mix64((static_cast<std::uint64_t>(static_cast<std::uint32_t>(col >> shift)) << 32) ^
               static_cast<std::uint32_t>(row >> shift) ^
               (static_cast<std::uint64_t>(floor) << 58) ^ (furniture ? 1ULL << 57 : 0));
}

float SurfaceLook::ValueNoise(float x, float y, std::uint64_t salt) const {
  // Bilinear value noise on the unit lattice, in [-1, 1].
  const float fx = FloorF(x), fy = FloorF(y);
  const float tx = x - fx, ty = y - fy;
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const auto v = [&](std::int64_t a, std::int64_t b) {
    return static_cast<float>(Key2(Key2(seed_ ^ salt, a), b) >> 40) * 0x1.0p-23f - 1.0f;
  };
  const float top = v(ix, iy) + (v(ix + 1, iy) - v(ix, iy)) * tx;
  const float bottom = v(ix, iy + 1) + (v(ix + 1, iy + 1) - v(ix, iy + 1)) * tx;
  return top + (bottom - top) * ty;
}

Rgb SurfaceLook::Furniture(const WallSurface& w, float h) const {
  // Tall cupboards (the 2.5-D renderer draws furniture full height): doors 0.5 m wide, shelves.
  const std::uint64_t piece = w.block_key ^ seed_;
  const Rgb base = (piece & 1u) != 0 ? kWood : kWhiteLaminate;
  float s = 1.0f;
  if ((piece & 1u) != 0) {
    // Wood grain: stretched noise along the height.
    s *= 1.0f + 0.10f * ValueNoise(w.along_m * 40.0f, h * 2.0f, 0x77);
  }
  const float door = Frac(w.along_m * 2.0f);  // 0.5 m doors
  if (door < 0.02f || door > 0.98f) s *= 0.55f;
  if (std::abs(h - 0.9f) < 0.015f || std::abs(h - 1.8f) < 0.015f) s *= 0.6f;
  if (h < 0.1f) s *= 0.5f;  // plinth
  // Handles: small dark bars beside the door edge at 1.0 m.
  if (door > 0.86f && door < 0.9f && h > 0.95f && h < 1.12f) s *= 0.3f;
  return Scale(base, s);
}

Rgb SurfaceLook::Wall(const WallSurface& w, float h) const {
  if (w.furniture) return Furniture(w, h);
  if (w.end_m < 0.08f && h < 2.1f) return kFrame;  // door frame at an opening
  const std::uint64_t block = w.block_key ^ seed_;
  Rgb c = kWallPalette[block % std::size(kWallPalette)];
  const std::uint32_t finish = static_cast<std::uint32_t>(block >> 20) & 3u;
  float s = 1.0f;
  const float a = w.along_m;
  switch (finish) {
    case 0:  // plaster
      s *= 1.0f + 0.05f * ValueNoise(a * 5.0f, h * 5.0f, w.face_key);
      break;
    case 1:  // tiles below 1.2 m
      if (h < 1.2f) {
        c = kTilePalette[(block >> 8) % std::size(kTilePalette)];
        const float tu = a * 5.0f, tv = h * 5.0f;
        if (Frac(tu) < 0.06f || Frac(tv) < 0.06f) {
          s *= 0.62f;  // grout
        } else {
          s *= 0.94f + 0.12f * static_cast<float>(Key2(Key2(w.face_key, Cell(tu)), Cell(tv)) & 255u) / 255.0f;
        }
      }
      break;
    case 2:  // wood boards below 1.0 m
      if (h < 1.0f) {
        c = kBoard;
        const float board = a * (1.0f / 0.12f);
        s *= Frac(board) < 0.08f ? 0.6f : 0.9f + 0.2f * static_cast<float>(Key2(w.face_key, Cell(board)) & 255u) / 255.0f;
        if (std::abs(h - 1.0f) < 0.025f) s *= 0.7f;  // capping rail
      }
      break;
    default: {  // wallpaper: a diamond motif of 0.3 m
      const float du = std::abs(Frac(a * (1.0f / 0.3f)) - 0.5f);
      const float dv = std::abs(Frac(h * (1.0f / 0.3f)) - 0.5f);
      if (du + dv < 0.22f) c = kPaperAccent;
      break;
    }
  }
  if (h < 0.12f) s *= 0.55f;                                   // skirting
  if (h > 0.86f && h < 0.94f) s *= h > 0.91f ? 1.08f : 0.72f;  // hand rail, lit from above
  if (Frac(a * (1.0f / 1.2f)) < 0.015f) s *= 0.8f;            // panel seam
  c = Scale(c, s);

  // Posters on a 2.4 m grid: one in three slots, a design from the catalogue.
  const std::int64_t slot = Cell(a * (1.0f / 2.4f));
  const std::uint64_t ph = Key2(w.face_key ^ seed_, slot);
  const float px = a - static_cast<float>(slot) * 2.4f - 0.85f;  // 0..0.7 across the poster
  if (ph % 3 == 0 && px >= 0.0f && px < 0.7f && h >= 1.25f && h < 2.05f) {
    const float py = 2.05f - h;  // 0..0.8 down the poster
    if (px < 0.03f || px > 0.67f || py < 0.03f || py > 0.77f) return {40, 40, 45};  // frame
    const std::uint64_t design = repeated_ ? (ph >> 8) % kPosterDesigns : ph >> 8;
    // A 5 x 7 grid of blocks, each one ink from the design; a title bar on top.
    if (py < 0.16f) return kPosterInk[design % std::size(kPosterInk)];
    const std::int64_t gx = Cell((px - 0.03f) * (5.0f / 0.64f));
    const std::int64_t gy = Cell((py - 0.16f) * (7.0f / 0.61f));
    const std::uint64_t cell = Key2(Key2(design * 0x51ED27ULL, gx), gy);
    return kPosterInk[cell % std::size(kPosterInk)];
  }
  // Signs on a 6 m grid, above the posters: dark glyphs on white, from the sign catalogue.
  const std::int64_t sslot = Cell(a * (1.0f / 6.0f));
  const std::uint64_t sh = Key2(w.face_key ^ (seed_ * 3), sslot);
  const float sx = a - static_cast<float>(sslot) * 6.0f - 2.5f;  // 0..1.0 across the sign
  if (sh % 2 == 0 && sx >= 0.0f && sx < 1.0f && h >= 2.1f && h < 2.35f) {
    const float sy = 2.35f - h;
    if (sx < 0.02f || sx > 0.98f || sy < 0.02f || sy > 0.23f) return {30, 60, 120};
    const std::uint64_t design = repeated_ ? (sh >> 8) % kSignDesigns : sh >> 8;
    // Ten glyphs of 3 x 4 strokes: a glyph cell is ink or paper.
    const std::int64_t gx = Cell((sx - 0.05f) * (30.0f / 0.9f));
    const std::int64_t gy = Cell((sy - 0.05f) * (4.0f / 0.13f));
    if (sx < 0.05f || sx >= 0.95f || sy < 0.05f || sy >= 0.18f || gx % 3 == 2) return {245, 245, 240};
    const std::uint64_t stroke = Key2(Key2(design * 0xA24BAEDULL, gx), gy);
    return (stroke & 3u) != 0 ? Rgb{25, 25, 30} : Rgb{245, 245, 240};
  }
  return c;
}

Rgb SurfaceLook::Floor(float x, float y) const {
  const float tu = x * (1.0f / 0.6f), tv = y * (1.0f / 0.6f);
  const std::int64_t cx = Cell(tu), cy = Cell(tv);
  float s = 0.92f + 0.12f * static_cast<float>(Key2(Key2(seed_ ^ 0xF1, cx), cy) & 255u) / 255.0f;
  if (Frac(tu) < 0.03f || Frac(tv) < 0.03f) s *= 0.8f;  // grout
  // Vinyl speckle: 3 cm cells, one in sixteen a little darker, one in thirty-two lighter (a
  // hospital floor is plain: it must not make every place unique by itself).
  const std::uint64_t speck = Key2(Key2(seed_ ^ 0x5EC, Cell(x * 33.3f)), Cell(y * 33.3f));
  if ((speck & 15u) == 0) {
    s *= 0.85f;
  } else if ((speck & 31u) == 1) {
    s *= 1.08f;
  }
  return Scale(kFloor, s);
}

Rgb SurfaceLook::Ceiling(float x, float y) const {
  const float tu = x * (1.0f / 1.2f), tv = y * (1.0f / 1.2f);
  const float fu = FloorF(tu), fv = FloorF(tv);
  if (tu - fu < 0.02f || tv - fv < 0.02f) return Scale(kCeiling, 0.85f);
  const int parity = static_cast<int>(fu) + 3 * static_cast<int>(fv);
  if ((parity & 3) == 0) return {255.0f, 255.0f, 250.0f};  // a light panel
  return Scale(kCeiling, 1.0f + 0.03f * ValueNoise(x * 12.0f, y * 12.0f, 0xCE));
}

}  // namespace zm::sim
