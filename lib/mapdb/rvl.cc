// RVL depth codec in RTAB-Map's container; see rvl.h for the format and the decoder's guarantees.
// Written from the published algorithm; words are assembled byte by byte so the code is
// independent of host endianness and alignment.
#include "mapdb/rvl.h"

#include <cstring>
#include <string>

namespace zm {
namespace {

constexpr char kMagic[8] = {'D', 'E', 'P', 'T', 'H', 'R', 'V', 'L'};

class NibbleWriter {
 public:
  explicit NibbleWriter(std::vector<std::byte>& out) : out_(out) {}
  void Vle(std::uint32_t value) {
    do {
      std::uint32_t nibble = value & 0x7u;
      value >>= 3;
      if (value != 0) nibble |= 0x8u;
      word_ = (word_ << 4) | nibble;
      if (++nibbles_ == 8) Flush();
    } while (value != 0);
  }
  void Finish() {
    if (nibbles_ > 0) {
      word_ <<= 4 * (8 - nibbles_);
      Flush();
    }
  }

 private:
  void Flush() {
    for (int i = 0; i < 4; ++i) out_.push_back(static_cast<std::byte>((word_ >> (8 * i)) & 0xffu));
    word_ = 0;
    nibbles_ = 0;
  }
  std::vector<std::byte>& out_;
  std::uint32_t word_ = 0;
  int nibbles_ = 0;
};

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

void PutU32(std::vector<std::byte>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xffu));
}

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
  std::vector<std::byte> out;
  out.reserve(kRvlHeaderBytes + depth.pixels.size() * 3 / 2 + 8);
  for (char c : kMagic) out.push_back(static_cast<std::byte>(c));
  PutU32(out, depth.width);
  PutU32(out, depth.height);
  NibbleWriter w(out);
  const std::size_t n = depth.pixels.size();
  std::size_t i = 0;
  std::int32_t previous = 0;
  while (i < n) {
    std::uint32_t zeros = 0;
    while (i < n && depth.pixels[i] == 0) {
      ++i;
      ++zeros;
    }
    w.Vle(zeros);
    std::uint32_t nonzeros = 0;
    for (std::size_t j = i; j < n && depth.pixels[j] != 0; ++j) ++nonzeros;
    w.Vle(nonzeros);
    for (std::uint32_t k = 0; k < nonzeros; ++k, ++i) {
      const std::int32_t current = depth.pixels[i];
      const std::int32_t delta = current - previous;
      // Zig-zag: small magnitudes of either sign become small unsigned values.
      w.Vle(static_cast<std::uint32_t>((delta << 1) ^ (delta >> 31)));
      previous = current;
    }
  }
  w.Finish();
  return out;
}

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
  NibbleReader r(blob.subspan(kRvlHeaderBytes));
  const auto fail = [&](std::uint64_t at, const char* why) {
    return Corrupt("RVL depth " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                   " (" + std::to_string(blob.size()) + " bytes): " + why + " at pixel " +
                   std::to_string(at));
  };
  std::uint64_t at = 0;
  std::int32_t previous = 0;
  while (at < n) {
    std::uint32_t zeros = 0, nonzeros = 0;
    if (!r.Vle(zeros)) return fail(at, "stream ends or overlong value");
    if (zeros > n - at) return fail(at, "zero run past the image end");
    at += zeros;  // pixels are already zero
    if (!r.Vle(nonzeros)) return fail(at, "stream ends or overlong value");
    if (nonzeros > n - at) return fail(at, "value run past the image end");
    for (std::uint32_t k = 0; k < nonzeros; ++k, ++at) {
      std::uint32_t positive = 0;
      if (!r.Vle(positive)) return fail(at, "stream ends or overlong value");
      const auto delta = static_cast<std::int32_t>((positive >> 1) ^ (0u - (positive & 1u)));
      const std::int32_t current = previous + delta;
      if (current < 0 || current > 0xffff) return fail(at, "depth outside 16 bits");
      img.pixels[static_cast<std::size_t>(at)] = static_cast<std::uint16_t>(current);
      previous = current;
    }
  }
  return img;
}

}  // namespace zm
