// RVL depth codec in RTAB-Map's container; see rvl.h for the format and the decoder's guarantees.
// Written from the published algorithm; words are assembled byte by byte so the code is
// independent of host endianness and alignment.
#include "mapdb/rvl.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>

namespace zm {
namespace {

constexpr char kMagic[8] = {'D', 'E', 'P', 'T', 'H', 'R', 'V', 'L'};

class NibbleReader {
 public:
  explicit NibbleReader(std::span<const std::byte> in) : in_(in) {}
  // False when the input ends or the value needs more than 32 bits.
  bool Vle(std::uint32_t& value) {
    value = 0;
    int shift = 0;
    std::uint32_t nibble;
    do {
      if (nibbles_ == 0) {
        if (pos_ + 4 > in_.size()) return false;
        word_ = 0;
        for (int i = 0; i < 4; ++i) {
          word_ |= static_cast<std::uint32_t>(in_[pos_ + static_cast<std::size_t>(i)]) << (8 * i);
        }
        pos_ += 4;
        nibbles_ = 8;
      }
      nibble = word_ >> 28;
      word_ <<= 4;
      --nibbles_;
      if (shift > 30) return false;
      value |= (nibble & 0x7u) << shift;
      shift += 3;
    } while ((nibble & 0x8u) != 0);
    return true;
  }

 private:
  std::span<const std::byte> in_;
  std::size_t pos_ = 0;
  std::uint32_t word_ = 0;
  int nibbles_ = 0;
};

std::uint32_t GetU32(std::span<const std::byte> b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(b[at + i]) << (8 * i);
  return v;
}

}  // namespace

bool IsRvlDepth(std::span<const std::byte> blob) {
  return blob.size() >= sizeof kMagic && std::memcmp(blob.data(), kMagic, sizeof kMagic) == 0;
}

std::vector<std::byte> EncodeRvlDepth(const DepthImage16& depth) {
  // Written straight into a buffer sized for ~2 bytes a pixel (noisy depth takes 1 to 1.5) and
  // grown, if ever, before a run that might not fit: the simulator encodes gigabytes with it.
  const std::size_t n = depth.pixels.size();
  const std::uint16_t* px = depth.pixels.data();
  std::vector<std::byte> out(kRvlHeaderBytes + 2 * n + 64);
  for (std::size_t i = 0; i < sizeof kMagic; ++i) out[i] = static_cast<std::byte>(kMagic[i]);
  for (int i = 0; i < 4; ++i) {
    out[8 + static_cast<std::size_t>(i)] = static_cast<std::byte>((depth.width >> (8 * i)) & 0xffu);
    out[12 + static_cast<std::size_t>(i)] = static_cast<std::byte>((depth.height >> (8 * i)) & 0xffu);
  }
  std::size_t pos = kRvlHeaderBytes;
  // Nibbles gather in `acc` (most significant first, as the stream wants) and leave it a 32-bit
  // word at a time, little-endian. Values below 512 (1 to 3 nibbles: almost every delta of real
  // or simulated depth) come packed from a table, without a loop or a branch per nibble.
  static const std::array<std::uint16_t, 512> kPacked = [] {
    std::array<std::uint16_t, 512> t{};
    for (std::uint32_t v = 0; v < 512; ++v) {
      std::uint32_t packed = 0, count = 0, rest = v;
      do {
        std::uint32_t nibble = rest & 0x7u;
        rest >>= 3;
        if (rest != 0) nibble |= 0x8u;
        packed = (packed << 4) | nibble;
        ++count;
      } while (rest != 0);
      t[v] = static_cast<std::uint16_t>(packed | (count << 12));
    }
    return t;
  }();
  std::uint64_t acc = 0;
  unsigned bits = 0;
  const auto put = [&](std::uint64_t packed, unsigned count) {
    acc = (acc << (4 * count)) | packed;
    bits += 4 * count;
    if (bits >= 32) {
      bits -= 32;
      const auto word = static_cast<std::uint32_t>(acc >> bits);
      for (unsigned b = 0; b < 4; ++b) out[pos + b] = static_cast<std::byte>((word >> (8 * b)) & 0xffu);
      pos += 4;
      acc &= (std::uint64_t{1} << bits) - 1;
    }
  };
  const auto vle = [&](std::uint32_t value) {
    if (value < kPacked.size()) {
      const std::uint16_t t = kPacked[value];
      put(t & 0xfffu, t >> 12u);
      return;
    }
    do {  // 4+ nibbles: one at a time, least significant value bits first
      std::uint32_t nibble = value & 0x7u;
      value >>= 3;
      if (value != 0) nibble |= 0x8u;
      put(nibble, 1);
    } while (value != 0);
  };
  std::size_t i = 0;
  std::int32_t previous = 0;
  while (i < n) {
    std::size_t j = i;
    while (j < n && px[j] == 0) ++j;
    const auto zeros = static_cast<std::uint32_t>(j - i);
    i = j;
    while (j < n && px[j] != 0) ++j;
    const auto nonzeros = static_cast<std::uint32_t>(j - i);
    // Worst case for this run: two 32-bit lengths (11 nibbles each) and 6 nibbles per value.
    const std::size_t need = pos + 4 * ((22 + 6 * std::size_t{nonzeros}) / 8 + 2);
    if (need > out.size()) out.resize(std::max(need, 2 * out.size()));
    vle(zeros);
    vle(nonzeros);
    for (; i < j; ++i) {
      const std::int32_t current = px[i];
      const std::int32_t delta = current - previous;
      // Zig-zag: small magnitudes of either sign become small unsigned values.
      vle(static_cast<std::uint32_t>((delta << 1) ^ (delta >> 31)));
      previous = current;
    }
  }
  if (bits > 0) {
    const auto word = static_cast<std::uint32_t>(acc << (32 - bits));
    for (unsigned b = 0; b < 4; ++b) out[pos + b] = static_cast<std::byte>((word >> (8 * b)) & 0xffu);
    pos += 4;
  }
  out.resize(pos);
  return out;
}

namespace {

// The decoding loop, shared by both entry points: writes every pixel of `out` (n pixels).
Status DecodeRvlBody(std::span<const std::byte> blob, std::uint32_t width, std::uint32_t height,
                     std::span<std::uint16_t> out) {
  const std::uint64_t n = out.size();
  NibbleReader r(blob.subspan(kRvlHeaderBytes));
  const auto fail = [&](std::uint64_t at, const char* why) {
    return Corrupt("RVL depth " + std::to_string(width) + "x" + std::to_string(height) + " (" +
                   std::to_string(blob.size()) + " bytes): " + why + " at pixel " +
                   std::to_string(at));
  };
  std::uint64_t at = 0;
  std::int32_t previous = 0;
  while (at < n) {
    std::uint32_t zeros = 0, nonzeros = 0;
    if (!r.Vle(zeros)) return fail(at, "stream ends or overlong value");
    if (zeros > n - at) return fail(at, "zero run past the image end");
    std::fill_n(out.data() + at, zeros, std::uint16_t{0});
    at += zeros;
    if (!r.Vle(nonzeros)) return fail(at, "stream ends or overlong value");
    if (nonzeros > n - at) return fail(at, "value run past the image end");
    for (std::uint32_t k = 0; k < nonzeros; ++k, ++at) {
      std::uint32_t positive = 0;
      if (!r.Vle(positive)) return fail(at, "stream ends or overlong value");
      const auto delta = static_cast<std::int32_t>((positive >> 1) ^ (0u - (positive & 1u)));
      const std::int32_t current = previous + delta;
      if (current < 0 || current > 0xffff) return fail(at, "depth outside 16 bits");
      out[static_cast<std::size_t>(at)] = static_cast<std::uint16_t>(current);
      previous = current;
    }
  }
  return Status::Ok();
}

}  // namespace

Result<DepthImage16> DecodeRvlDepth(std::span<const std::byte> blob) {
  if (blob.size() < kRvlHeaderBytes || !IsRvlDepth(blob)) {
    return Corrupt("RVL depth of " + std::to_string(blob.size()) +
                   " bytes has no 16-byte DEPTHRVL header");
  }
  DepthImage16 img;
  img.width = GetU32(blob, 8);
  img.height = GetU32(blob, 12);
  const std::uint64_t n = std::uint64_t{img.width} * img.height;
  if (n == 0 || n > kRvlMaxPixels) {
    return Corrupt("RVL depth header claims " + std::to_string(img.width) + "x" +
                   std::to_string(img.height) + " pixels (limit " + std::to_string(kRvlMaxPixels) +
                   ")");
  }
  img.pixels.resize(static_cast<std::size_t>(n));
  ZM_RETURN_IF_ERROR(DecodeRvlBody(blob, img.width, img.height, img.pixels));
  return img;
}

Status DecodeRvlDepthInto(std::span<const std::byte> blob, std::uint32_t width, std::uint32_t height,
                          std::span<std::uint16_t> out) {
  if (blob.size() < kRvlHeaderBytes || !IsRvlDepth(blob)) {
    return Corrupt("RVL depth of " + std::to_string(blob.size()) +
                   " bytes has no 16-byte DEPTHRVL header");
  }
  const std::uint32_t w = GetU32(blob, 8), h = GetU32(blob, 12);
  if (w != width || h != height) {
    return Corrupt("RVL depth header says " + std::to_string(w) + "x" + std::to_string(h) +
                   ", the keyframe's dense image is " + std::to_string(width) + "x" +
                   std::to_string(height));
  }
  if (out.size() != std::uint64_t{width} * height) {
    return InvalidArgument("RVL output of " + std::to_string(out.size()) + " pixels for a " +
                           std::to_string(width) + "x" + std::to_string(height) + " image");
  }
  return DecodeRvlBody(blob, width, height, out);
}

}  // namespace zm
