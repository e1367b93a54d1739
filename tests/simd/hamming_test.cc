// Hamming kernels: the scalar reference against a bit-by-bit oracle, the NEON kernel (when built)
// against the scalar reference on seeded random inputs, lengths around the vector width, every
// misalignment and the edge cases; and a check that an aarch64 build did not silently fall back
// to scalar (invariant 6, docs/style.md §7).
#include "simd/hamming.h"

#include <doctest/doctest.h>

#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#ifndef ZM_FORCE_SCALAR
#error "the build passes ZM_FORCE_SCALAR=0/1 to this test"
#endif

namespace zm::simd {
namespace {

// A kernel set under test (lambdas resolve the overloads).
struct Kernel {
  std::string name;
  std::function<void(const std::uint8_t*, const std::uint8_t*, std::size_t, std::uint16_t*)> one16;
  std::function<void(const std::uint8_t*, const std::uint8_t*, std::size_t, std::uint32_t*)> one32;
  std::function<void(const std::uint8_t*, std::size_t, const std::uint8_t*, std::size_t, BestTwo*)>
      best_two;
  std::function<std::size_t(const std::uint8_t*, std::size_t, const std::uint8_t*, std::size_t,
                            const RatioTestParams&, DescriptorMatch*)>
      ratio;
};

#define ZM_KERNEL(ns)                                                                       \
  Kernel {                                                                                  \
    ns::KernelName(),                                                                       \
        [](const std::uint8_t* q, const std::uint8_t* t, std::size_t n, std::uint16_t* o) { \
          ns::HammingOneToMany(q, t, n, o);                                                 \
        },                                                                                  \
        [](const std::uint8_t* q, const std::uint8_t* t, std::size_t n, std::uint32_t* o) { \
          ns::HammingOneToMany(q, t, n, o);                                                 \
        },                                                                                  \
        [](const std::uint8_t* q, std::size_t nq, const std::uint8_t* t, std::size_t nt,    \
           BestTwo* o) { ns::BestTwoMatches(q, nq, t, nt, o); },                            \
        [](const std::uint8_t* q, std::size_t nq, const std::uint8_t* t, std::size_t nt,    \
           const RatioTestParams& p,                                                        \
           DescriptorMatch* o) { return ns::MatchRatioTest(q, nq, t, nt, p, o); }           \
  }

std::vector<Kernel> Kernels() {
  std::vector<Kernel> k{ZM_KERNEL(scalar)};
#if ZM_SIMD_NEON
  k.push_back(ZM_KERNEL(neon));
#endif
  return k;
}

// Oracle: count differing bits one by one.
std::uint32_t OracleDistance(const std::uint8_t* a, const std::uint8_t* b) {
  std::uint32_t d = 0;
  for (std::size_t i = 0; i < kHammingBytes; ++i) {
    for (int bit = 0; bit < 8; ++bit) d += ((a[i] ^ b[i]) >> bit) & 1u;
  }
  return d;
}

// n descriptors placed `offset` bytes past a 16-byte aligned base (the vector keeps it alive).
struct Placed {
  std::vector<std::uint8_t> storage;
  std::uint8_t* ptr = nullptr;
};
Placed Place(const std::vector<std::uint8_t>& bytes, std::size_t offset) {
  Placed p;
  p.storage.assign(bytes.size() + 64, 0xA5);
  auto base = reinterpret_cast<std::uintptr_t>(p.storage.data());
  const std::size_t aligned = (16 - base % 16) % 16;
  p.ptr = p.storage.data() + aligned + offset;
  if (!bytes.empty()) std::memcpy(p.ptr, bytes.data(), bytes.size());
  return p;
}

// Random descriptors; `clustered` makes them near copies of a few bases so distances are small
// and ties frequent (the ratio test's hard cases).
std::vector<std::uint8_t> RandomDescriptors(std::mt19937& rng, std::size_t n, bool clustered) {
  std::vector<std::uint8_t> d(n * kHammingBytes);
  std::uniform_int_distribution<int> byte(0, 255);
  for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
  if (clustered && n > 0) {
    std::uniform_int_distribution<std::size_t> pick(0, 2);
    std::uniform_int_distribution<std::size_t> bitpos(0, 255);
    for (std::size_t i = 0; i < n; ++i) {
      std::memcpy(&d[i * kHammingBytes], &d[pick(rng) % n * kHammingBytes], kHammingBytes);
      for (int f = 0; f < 3; ++f) {
        const std::size_t b = bitpos(rng);
        d[i * kHammingBytes + b / 8] ^= static_cast<std::uint8_t>(1u << (b % 8));
      }
    }
  }
  return d;
}

BestTwo OracleBestTwo(const std::uint8_t* q, const std::uint8_t* t, std::size_t nt) {
  BestTwo b;
  std::vector<std::uint32_t> d(nt);
  for (std::size_t i = 0; i < nt; ++i) d[i] = OracleDistance(q, t + i * kHammingBytes);
  if (nt == 0) return b;
  std::size_t bi = 0;
  for (std::size_t i = 1; i < nt; ++i)
    if (d[i] < d[bi]) bi = i;
  b.best_index = static_cast<std::uint32_t>(bi);
  b.best_distance = static_cast<std::uint16_t>(d[bi]);
  for (std::size_t i = 0; i < nt; ++i) {
    if (i != bi && d[i] < b.second_distance) b.second_distance = static_cast<std::uint16_t>(d[i]);
  }
  return b;
}

bool Same(const BestTwo& a, const BestTwo& b) {
  return a.best_index == b.best_index && a.best_distance == b.best_distance &&
         a.second_distance == b.second_distance;
}

const std::vector<std::size_t> kLengths{0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10,
                                        11, 12, 13, 14, 15, 16, 17, 31, 32, 33, 257};

TEST_CASE("the active kernel is the one the build promised (no silent scalar on aarch64)") {
  const std::string active = ActiveHammingKernel();
#if ZM_SIMD_NEON
  CHECK(active == "neon");
  CHECK(std::string(neon::KernelName()) == "neon");
#else
  CHECK(active == "scalar");
#endif
#if defined(__aarch64__) && !ZM_FORCE_SCALAR
  // An aarch64 build without ZM_FORCE_SCALAR must have compiled and selected NEON.
  CHECK_MESSAGE(ZM_SIMD_NEON == 1, "aarch64 build silently used the scalar kernel");
  CHECK(active == "neon");
#endif
#if ZM_FORCE_SCALAR
  CHECK(active == "scalar");
#endif
  MESSAGE("active Hamming kernel: " << active);
}

TEST_CASE("one-to-many: every kernel equals the oracle, all lengths, all misalignments") {
  std::mt19937 rng(1234);
  for (const Kernel& k : Kernels()) {
    for (std::size_t n : kLengths) {
      const auto query = RandomDescriptors(rng, 1, false);
      const auto train = RandomDescriptors(rng, n, n % 2 == 1);
      std::vector<std::uint32_t> expected(n);
      for (std::size_t i = 0; i < n; ++i) {
        expected[i] = OracleDistance(query.data(), train.data() + i * kHammingBytes);
      }
      for (std::size_t off = 0; off < 16; ++off) {
        const Placed t = Place(train, off);
        const Placed q = Place(query, (off * 7 + 3) % 16);
        std::vector<std::uint16_t> d16(n + 1, 0xBEEF);  // sentinel past the end
        std::vector<std::uint32_t> d32(n + 1, 0xDEADBEEF);
        k.one16(q.ptr, t.ptr, n, d16.data());
        k.one32(q.ptr, t.ptr, n, d32.data());
        bool ok = d16[n] == 0xBEEF && d32[n] == 0xDEADBEEF;
        for (std::size_t i = 0; i < n; ++i)
          ok = ok && d16[i] == expected[i] && d32[i] == expected[i];
        CHECK_MESSAGE(ok, k.name << " n=" << n << " offset=" << off);
      }
    }
  }
}

TEST_CASE("best-two and ratio test: every kernel equals the oracle, all lengths, misalignments") {
  std::mt19937 rng(99);
  const RatioTestParams params{0.8f, 40};
  for (const Kernel& k : Kernels()) {
    for (std::size_t nt : kLengths) {
      for (bool clustered : {false, true}) {
        const std::size_t nq = 9;
        auto queries = RandomDescriptors(rng, nq, false);
        const auto train = RandomDescriptors(rng, nt, clustered);
        // Make some queries near copies of trains so matches and ties occur.
        for (std::size_t i = 0; i < nq && nt > 0; i += 2) {
          std::memcpy(&queries[i * kHammingBytes], &train[(i * 5 % nt) * kHammingBytes],
                      kHammingBytes);
          queries[i * kHammingBytes + i % kHammingBytes] ^= static_cast<std::uint8_t>(i);
        }
        std::vector<BestTwo> expected(nq);
        for (std::size_t q = 0; q < nq; ++q) {
          expected[q] = OracleBestTwo(&queries[q * kHammingBytes], train.data(), nt);
        }
        for (std::size_t off = 0; off < 16; ++off) {
          const Placed t = Place(train, off);
          const Placed q = Place(queries, 15 - off);
          std::vector<BestTwo> got(nq);
          k.best_two(q.ptr, nq, t.ptr, nt, got.data());
          std::vector<DescriptorMatch> m(nq);
          const std::size_t count = k.ratio(q.ptr, nq, t.ptr, nt, params, m.data());
          bool ok = true;
          std::size_t expected_count = 0;
          for (std::size_t i = 0; i < nq; ++i) {
            ok = ok && Same(got[i], expected[i]);
            if (PassesRatioTest(expected[i], params)) {
              ok = ok && expected_count < count && m[expected_count].query == i &&
                   m[expected_count].train == expected[i].best_index &&
                   m[expected_count].distance == expected[i].best_distance;
              ++expected_count;
            }
          }
          ok = ok && count == expected_count;
          CHECK_MESSAGE(ok,
                        k.name << " nt=" << nt << " offset=" << off << " clustered=" << clustered);
        }
      }
    }
  }
}

TEST_CASE("edge cases: all-zero vs all-ones (256), single bits, empty train") {
  std::vector<std::uint8_t> zeros(kHammingBytes, 0x00);
  std::vector<std::uint8_t> ones(5 * kHammingBytes, 0xFF);
  std::vector<std::uint8_t> bits(256 * kHammingBytes, 0x00);
  for (std::size_t b = 0; b < 256; ++b) {
    bits[b * kHammingBytes + b / 8] = static_cast<std::uint8_t>(1u << (b % 8));
  }
  for (const Kernel& k : Kernels()) {
    std::vector<std::uint16_t> d16(5);
    std::vector<std::uint32_t> d32(5);
    k.one16(zeros.data(), ones.data(), 5, d16.data());
    k.one32(zeros.data(), ones.data(), 5, d32.data());
    for (int i = 0; i < 5; ++i) {
      CHECK(d16[static_cast<std::size_t>(i)] == 256);
      CHECK(d32[static_cast<std::size_t>(i)] == 256);
    }
    k.one16(ones.data(), ones.data(), 5, d16.data());
    CHECK(d16[4] == 0);
    std::vector<std::uint16_t> b16(256);
    k.one16(zeros.data(), bits.data(), 256, b16.data());
    bool all_one = true;
    for (auto d : b16) all_one = all_one && d == 1;
    CHECK_MESSAGE(all_one, k.name);
    BestTwo b;
    k.best_two(zeros.data(), 1, ones.data(), 0, &b);
    CHECK(b.best_index == kNoMatch);
    CHECK(b.second_distance == kNoSecond);
    k.best_two(zeros.data(), 1, ones.data(), 1, &b);
    CHECK(b.best_index == 0);
    CHECK(b.best_distance == 256);
    CHECK(b.second_distance == kNoSecond);
    DescriptorMatch m;
    CHECK(k.ratio(zeros.data(), 1, ones.data(), 0, RatioTestParams{}, &m) == 0);
  }
}

TEST_CASE("ratio test ties: equal best and second reject, boundary values, max distance gate") {
  // train: [A, A, C]: query A has best 0 (first of the tie) and second 0 -> rejected.
  std::vector<std::uint8_t> train(3 * kHammingBytes, 0x00);
  train[2 * kHammingBytes] = 0xFF;  // C differs from A by 8 bits
  std::vector<std::uint8_t> q(kHammingBytes, 0x00);
  for (const Kernel& k : Kernels()) {
    BestTwo b;
    k.best_two(q.data(), 1, train.data(), 3, &b);
    CHECK(b.best_index == 0);
    CHECK(b.best_distance == 0);
    CHECK(b.second_distance == 0);
    DescriptorMatch m;
    CHECK(k.ratio(q.data(), 1, train.data(), 3, RatioTestParams{0.8f, 64}, &m) == 0);
    // Only [A, C]: best 0 < 0.8 * 8: accepted.
    CHECK(k.ratio(q.data(), 1, train.data() + kHammingBytes, 2, RatioTestParams{0.8f, 64}, &m) ==
          1);
    CHECK(m.train == 0);
  }
  // The shared predicate at its boundaries: 8 < 0.8 * 10 is false (strict), 7 is accepted.
  CHECK_FALSE(PassesRatioTest(BestTwo{0, 8, 10}, RatioTestParams{0.8f, 64}));
  CHECK(PassesRatioTest(BestTwo{0, 7, 10}, RatioTestParams{0.8f, 64}));
  CHECK(PassesRatioTest(BestTwo{0, 64, 200}, RatioTestParams{0.8f, 64}));
  CHECK_FALSE(PassesRatioTest(BestTwo{0, 65, 200}, RatioTestParams{0.8f, 64}));
  CHECK(PassesRatioTest(BestTwo{3, 30, kNoSecond}, RatioTestParams{0.8f, 64}));
  CHECK_FALSE(PassesRatioTest(BestTwo{}, RatioTestParams{0.8f, 256}));
}

TEST_CASE("dispatch functions call the active kernel") {
  std::mt19937 rng(5);
  const auto q = RandomDescriptors(rng, 3, false);
  const auto t = RandomDescriptors(rng, 70, true);
  std::vector<std::uint16_t> a(70), b(70);
  HammingOneToMany(q.data(), t.data(), 70, a.data());
  scalar::HammingOneToMany(q.data(), t.data(), 70, b.data());
  CHECK(a == b);
  BestTwo x[3], y[3];
  BestTwoMatches(q.data(), 3, t.data(), 70, x);
  scalar::BestTwoMatches(q.data(), 3, t.data(), 70, y);
  for (int i = 0; i < 3; ++i) CHECK(Same(x[i], y[i]));
}

}  // namespace
}  // namespace zm::simd
