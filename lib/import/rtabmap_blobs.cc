// RTAB-Map's blob formats (declared in rtabmap_import.h, the importer's building blocks): the
// zlib matrices of rtabmap::compressData2 (Admin.opt_ids, Admin.opt_poses) and the CameraModel
// serialization of Data.calibration. A size a blob claims is checked against the blob before
// anything is allocated (fuzz/rtabmap_blob_fuzz.cc feeds them arbitrary bytes).
#include <zlib.h>

#include <cstring>
#include <string>

#include "import/rtabmap_import.h"

namespace zm {

std::size_t RtabmapElementBytes(std::int32_t type) {
  static constexpr std::size_t kDepthBytes[8] = {1, 1, 2, 2, 4, 4, 8, 2};
  const auto depth = static_cast<std::size_t>(type & 7);
  const auto channels = static_cast<std::size_t>(1 + (type >> 3));
  return kDepthBytes[depth] * channels;
}

Result<RtabmapMatrix> UncompressRtabmapData(std::span<const std::byte> blob,
                                            const std::string& what) {
  if (blob.size() < 12) {
    return Corrupt(what + ": " + std::to_string(blob.size()) +
                   " bytes, shorter than the 12-byte rows/cols/type trailer");
  }
  RtabmapMatrix m;
  std::memcpy(&m.rows, blob.data() + blob.size() - 12, 4);
  std::memcpy(&m.cols, blob.data() + blob.size() - 8, 4);
  std::memcpy(&m.type, blob.data() + blob.size() - 4, 4);
  if (m.rows < 0 || m.cols < 0 || m.type < 0 || m.type >= 8 * 512) {
    return Corrupt(what + ": trailer claims " + std::to_string(m.rows) + "x" +
                   std::to_string(m.cols) + " of OpenCV type " + std::to_string(m.type) +
                   " (invalid)");
  }
  const std::uint64_t want =
      std::uint64_t(m.rows) * std::uint64_t(m.cols) * RtabmapElementBytes(m.type);
  constexpr std::uint64_t kLimit = 1ull << 30;
  if (want > kLimit) {
    return Corrupt(what + ": trailer claims " + std::to_string(want) + " bytes, limit " +
                   std::to_string(kLimit));
  }
  // Deflate expands at most 1032:1, so a claim beyond that is a lie: refuse it before
  // allocating (a 12-byte blob could otherwise make us zero-fill 1 GiB; found by
  // fuzz/rtabmap_blob_fuzz.cc).
  if (want > std::uint64_t{1032} * (blob.size() - 12)) {
    return Corrupt(what + ": trailer claims " + std::to_string(want) + " bytes from " +
                   std::to_string(blob.size() - 12) +
                   " bytes of zlib data (more than zlib's 1032:1)");
  }
  m.data.resize(static_cast<std::size_t>(want));
  uLongf got = static_cast<uLongf>(want);
  // zlib wants a non-null destination even for an empty matrix.
  Bytef empty = 0;
  const int zrc =
      uncompress(want > 0 ? reinterpret_cast<Bytef*>(m.data.data()) : &empty, &got,
                 reinterpret_cast<const Bytef*>(blob.data()), static_cast<uLong>(blob.size() - 12));
  const std::string claim = "trailer claims " + std::to_string(m.rows) + "x" +
                            std::to_string(m.cols) + " of OpenCV type " + std::to_string(m.type) +
                            " = " + std::to_string(want) + " bytes";
  if (zrc == Z_BUF_ERROR) return Corrupt(what + ": " + claim + ", but the data inflates to more");
  if (zrc != Z_OK) {
    return Corrupt(what + ": zlib data of " + std::to_string(blob.size() - 12) +
                   " bytes is corrupt (zlib error " + std::to_string(zrc) + ")");
  }
  if (got != want) {
    return Corrupt(what + ": " + claim + ", but the data inflates to " + std::to_string(got) +
                   " bytes");
  }
  return m;
}

std::vector<std::byte> CompressRtabmapData(const RtabmapMatrix& m) {
  uLongf n = compressBound(static_cast<uLong>(m.data.size()));
  std::vector<std::byte> out(n + 12);
  Bytef empty = 0;
  const int zrc = compress(reinterpret_cast<Bytef*>(out.data()), &n,
                           m.data.empty() ? &empty : reinterpret_cast<const Bytef*>(m.data.data()),
                           static_cast<uLong>(m.data.size()));
  if (zrc != Z_OK) return {};
  out.resize(n + 12);
  std::memcpy(out.data() + n, &m.rows, 4);
  std::memcpy(out.data() + n + 4, &m.cols, 4);
  std::memcpy(out.data() + n + 8, &m.type, 4);
  return out;
}

Result<CameraIntrinsics> ParseRtabmapCalibration(std::span<const std::byte> blob) {
  constexpr std::size_t kHeader = 11 * 4;
  if (blob.size() < kHeader) {
    return Corrupt("calibration of " + std::to_string(blob.size()) + " bytes is shorter than its " +
                   std::to_string(kHeader) + "-byte header");
  }
  std::int32_t h[11];
  std::memcpy(h, blob.data(), sizeof h);
  const std::int32_t k = h[6], d = h[7], r = h[8], p = h[9], t = h[10];
  const auto bad_count = [](std::int32_t c) { return c < 0 || c > 64; };
  if (h[4] < 0 || h[5] < 0 || bad_count(k) || bad_count(d) || bad_count(r) || bad_count(p) ||
      bad_count(t) || (k != 0 && k != 9) || (t != 0 && t != 12)) {
    return Corrupt("calibration header (" + std::to_string(h[4]) + "x" + std::to_string(h[5]) +
                   ", |K|=" + std::to_string(k) + " |D|=" + std::to_string(d) +
                   " |R|=" + std::to_string(r) + " |P|=" + std::to_string(p) +
                   " |T|=" + std::to_string(t) + ") is not a CameraModel of RTAB-Map >= 0.18");
  }
  const std::size_t need =
      kHeader + 8 * static_cast<std::size_t>(k + d + r + p) + 4 * static_cast<std::size_t>(t);
  if (blob.size() < need) {
    return Corrupt("calibration of " + std::to_string(blob.size()) + " bytes, its header needs " +
                   std::to_string(need));
  }
  CameraIntrinsics c;
  c.width = static_cast<std::uint32_t>(h[4]);
  c.height = static_cast<std::uint32_t>(h[5]);
  const auto at = [&](std::size_t index) {
    double v;
    std::memcpy(&v, blob.data() + kHeader + 8 * index, 8);
    return v;
  };
  if (k == 9) {
    c.fx = at(0), c.cx = at(2), c.fy = at(4), c.cy = at(5);
  } else if (p == 12) {
    const auto base = static_cast<std::size_t>(k + d + r);
    c.fx = at(base + 0), c.cx = at(base + 2), c.fy = at(base + 5), c.cy = at(base + 6);
  }
  return c;
}

}  // namespace zm
