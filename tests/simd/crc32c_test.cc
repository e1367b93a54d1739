// CRC-32C kernels: the scalar reference against a bit-by-bit oracle and the published check
// values, every hardware kernel built here against the scalar reference on seeded random
// inputs (every length 0..256, every misalignment, lengths around the three-stream block
// boundaries, large buffers, continuation from a previous CRC), the run-time choice (a build
// that expects hardware and silently runs scalar fails), and the force-scalar switch.
#include "simd/crc32c.h"

#include <doctest/doctest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#if ZM_CRC32C_ARMV8
#include <sys/auxv.h>
#ifndef HWCAP_CRC32
#define HWCAP_CRC32 (1 << 7)
#endif
#endif

#ifndef ZM_FORCE_SCALAR
#error "the build passes ZM_FORCE_SCALAR=0/1 to this test"
#endif

namespace zm::simd {
namespace {

using Fn = std::uint32_t (*)(const void*, std::size_t, std::uint32_t);
struct Kernel {
  std::string name;
  Fn fn;
};

std::vector<Kernel> Kernels() {
  std::vector<Kernel> k{{scalar::Crc32cKernelName(), &scalar::Crc32c}};
  // A hardware kernel is only run when the CPU has its instructions (else SIGILL).
#if ZM_CRC32C_SSE42
  if (Crc32cHardwareAvailable()) k.push_back({sse42::Crc32cKernelName(), &sse42::Crc32c});
#endif
#if ZM_CRC32C_ARMV8
  if (Crc32cHardwareAvailable()) k.push_back({armv8::Crc32cKernelName(), &armv8::Crc32c});
#endif
  return k;
}

// Oracle: the definition, one bit at a time.
std::uint32_t Oracle(const std::uint8_t* p, std::size_t n, std::uint32_t crc = 0) {
  std::uint32_t r = ~crc;
  for (std::size_t i = 0; i < n; ++i) {
    r ^= p[i];
    for (int b = 0; b < 8; ++b) r = (r & 1u) != 0 ? (r >> 1) ^ 0x82F63B78u : r >> 1;
  }
  return ~r;
}

std::vector<std::uint8_t> Random(std::mt19937& rng, std::size_t n) {
  std::vector<std::uint8_t> v(n);
  std::uniform_int_distribution<int> byte(0, 255);
  for (auto& b : v) b = static_cast<std::uint8_t>(byte(rng));
  return v;
}

// `bytes` copied `offset` bytes past a 64-byte aligned address (the vector keeps it alive).
struct Placed {
  std::vector<std::uint8_t> storage;
  const std::uint8_t* ptr = nullptr;
};
Placed Place(const std::vector<std::uint8_t>& bytes, std::size_t offset) {
  Placed p;
  p.storage.assign(bytes.size() + 128, 0xA5);
  const auto base = reinterpret_cast<std::uintptr_t>(p.storage.data());
  std::uint8_t* at = p.storage.data() + (64 - base % 64) % 64 + offset;
  if (!bytes.empty()) std::memcpy(at, bytes.data(), bytes.size());
  p.ptr = at;
  return p;
}

TEST_CASE("crc32c: the kernel in use is the one the build and the CPU promise") {
  const std::string active = ActiveCrc32cKernel();
  const std::string compiled = Crc32cHardwareKernel() != nullptr ? Crc32cHardwareKernel() : "none";
  MESSAGE("active CRC-32C kernel: " << active << " (compiled hardware kernel: " << compiled << ")");
#if defined(__x86_64__) && !ZM_FORCE_SCALAR
  CHECK_MESSAGE(ZM_CRC32C_SSE42 == 1, "x86-64 build without the SSE4.2 CRC-32C kernel");
#endif
#if defined(__aarch64__) && !ZM_FORCE_SCALAR
  CHECK_MESSAGE(ZM_CRC32C_ARMV8 == 1, "aarch64 build without the ARMv8 CRC-32C kernel");
#endif
#if ZM_FORCE_SCALAR
  CHECK(Crc32cHardwareKernel() == nullptr);
  CHECK(active == "scalar");
#endif
  // Where the CPU has the instructions, the hardware kernel must be the one in use. The CPU
  // is asked here directly, not through the library, so a broken detection fails too.
#if ZM_CRC32C_SSE42
  if (__builtin_cpu_supports("sse4.2")) {
    CHECK(Crc32cHardwareAvailable());
    CHECK_MESSAGE(active == "sse42", "SSE4.2 CPU, but CRC-32C runs the " << active << " kernel");
  } else {
    MESSAGE("this CPU has no SSE4.2: the scalar kernel is correct here, hardware not tested");
    CHECK(active == "scalar");
  }
#endif
#if ZM_CRC32C_ARMV8
  if ((getauxval(AT_HWCAP) & HWCAP_CRC32) != 0) {
    CHECK(Crc32cHardwareAvailable());
    CHECK_MESSAGE(active == "armv8", "CPU with the CRC extension, but CRC-32C runs " << active);
  } else {
    MESSAGE("this CPU has no ARMv8 CRC extension: scalar is correct here, hardware not tested");
    CHECK(active == "scalar");
  }
#endif
}

TEST_CASE("crc32c: published check values (RFC 3720 B.4 and the standard '123456789')") {
  std::vector<std::uint8_t> zeros(32, 0x00), ones(32, 0xFF), up(32), down(32);
  for (std::uint8_t i = 0; i < 32; ++i) {
    up[i] = i;
    down[i] = static_cast<std::uint8_t>(31 - i);
  }
  const char* digits = "123456789";
  for (const Kernel& k : Kernels()) {
    CAPTURE(k.name);
    CHECK(k.fn(digits, 9, 0) == 0xE3069283u);
    CHECK(k.fn(zeros.data(), 32, 0) == 0x8A9136AAu);
    CHECK(k.fn(ones.data(), 32, 0) == 0x62A8AB43u);
    CHECK(k.fn(up.data(), 32, 0) == 0x46DD794Eu);
    CHECK(k.fn(down.data(), 32, 0) == 0x113FDB5Cu);
    CHECK(k.fn(nullptr, 0, 0) == 0u);
    CHECK(k.fn(nullptr, 0, 0x12345678u) == 0x12345678u);
  }
  CHECK(Crc32c(digits, 9) == 0xE3069283u);
}

TEST_CASE("crc32c: scalar equals the bit-by-bit oracle, every length 0..256, continuation") {
  std::mt19937 rng(42);
  const auto data = Random(rng, 600);
  for (std::size_t n = 0; n <= 256; ++n) {
    CHECK_MESSAGE(scalar::Crc32c(data.data(), n) == Oracle(data.data(), n), "n=" << n);
  }
  for (std::size_t n : {257u, 511u, 600u}) CHECK(scalar::Crc32c(data.data(), n) == Oracle(data.data(), n));
  const std::uint32_t a = scalar::Crc32c(data.data(), 100);
  CHECK(scalar::Crc32c(data.data() + 100, 500, a) == Oracle(data.data(), 600));
}

TEST_CASE("crc32c: every kernel equals scalar, every length 0..256 at every misalignment") {
  std::mt19937 rng(7);
  for (const Kernel& k : Kernels()) {
    for (std::size_t n = 0; n <= 256; ++n) {
      const auto data = Random(rng, n);
      const std::uint32_t seed = static_cast<std::uint32_t>(rng());
      const std::uint32_t want = scalar::Crc32c(data.data(), n);
      const std::uint32_t want_seeded = scalar::Crc32c(data.data(), n, seed);
      bool ok = true;
      for (std::size_t off = 0; off < 16; ++off) {
        const Placed p = Place(data, off);
        ok = ok && k.fn(p.ptr, n, 0) == want && k.fn(p.ptr, n, seed) == want_seeded;
      }
      CHECK_MESSAGE(ok, k.name << " n=" << n);
    }
  }
}

TEST_CASE("crc32c: every kernel equals scalar around the three-stream blocks and on large buffers") {
  std::mt19937 rng(2024);
  // 3 x 256 and 3 x 8192 are the block sizes of the three-stream loops (crc32c_internal.h).
  std::vector<std::size_t> lengths;
  for (std::size_t base : {768u, 1536u, 24576u, 49152u, 24576u + 768u}) {
    for (std::size_t d = 0; d < 9; ++d) lengths.push_back(base + d - 4);
  }
  for (std::size_t n : {100'000u, 1'048'576u, 1'048'576u + 13u, 3'000'001u}) lengths.push_back(n);
  const auto data = Random(rng, 3'000'001 + 16);
  for (const Kernel& k : Kernels()) {
    for (std::size_t n : lengths) {
      for (std::size_t off : {0u, 1u, 3u, 7u, 13u}) {
        CHECK_MESSAGE(k.fn(data.data() + off, n, 0) == scalar::Crc32c(data.data() + off, n, 0),
                      k.name << " n=" << n << " offset=" << off);
      }
    }
    // Continuation across arbitrary split points equals the whole.
    const std::uint32_t whole = k.fn(data.data(), 1'048'576, 0);
    for (std::size_t split : {1u, 767u, 24575u, 500'000u}) {
      const std::uint32_t a = k.fn(data.data(), split, 0);
      CHECK_MESSAGE(k.fn(data.data() + split, 1'048'576 - split, a) == whole, k.name << " split=" << split);
    }
  }
}

TEST_CASE("crc32c: forcing scalar switches the dispatch and keeps the results") {
  std::mt19937 rng(3);
  const auto data = Random(rng, 100'000);
  const std::uint32_t before = Crc32c(data.data(), data.size());
  SetCrc32cForceScalar(true);
  CHECK(std::string(ActiveCrc32cKernel()) == "scalar");
  CHECK(Crc32c(data.data(), data.size()) == before);
  SetCrc32cForceScalar(false);
  CHECK(std::string(ActiveCrc32cKernel()) == (Crc32cHardwareAvailable() ? Crc32cHardwareKernel() : "scalar"));
}

}  // namespace
}  // namespace zm::simd
