// libFuzzer target: the RTAB-Map import blob decoders (lib/mapdb/rtabmap_import.h, rvl.h):
// the first input byte picks the decoder, the rest is the blob.
//   0: UncompressRtabmapData (zlib stream + 12-byte rows/cols/type trailer)
//   1: DecodeRvlDepth (the "DEPTHRVL" container)
//   2: ParseRtabmapCalibration (CameraModel::serialize)
// Any blob must give a value or an error; an accepted matrix must hold exactly rows * cols *
// RtabmapElementBytes(type) bytes, an accepted depth image width * height pixels.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "import/rtabmap_import.h"
#include "mapdb/rvl.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::span<const std::byte> blob(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  switch (data[0] % 3) {
    case 0: {
      auto m = zm::UncompressRtabmapData(blob, "fuzz");
      if (m.ok()) {
        if (m->rows < 0 || m->cols < 0) std::abort();
        // The decoder's own element size: a second table here once disagreed with it on CV_16F
        // (depth 7) and failed a correct decode (fuzz/regressions/rtabmap_blob/cv16f_2ch.bin).
        const std::size_t elem = zm::RtabmapElementBytes(m->type);
        if (m->data.size() !=
            static_cast<std::size_t>(m->rows) * static_cast<std::size_t>(m->cols) * elem) {
          std::abort();
        }
      } else if (m.status().message().empty()) {
        std::abort();
      }
      break;
    }
    case 1: {
      auto d = zm::DecodeRvlDepth(blob);
      if (d.ok()) {
        if (d->pixels.size() != std::size_t{d->width} * d->height) std::abort();
      } else if (d.status().message().empty()) {
        std::abort();
      }
      break;
    }
    default: {
      auto c = zm::ParseRtabmapCalibration(blob);
      if (!c.ok() && c.status().message().empty()) std::abort();
      break;
    }
  }
  return 0;
}
