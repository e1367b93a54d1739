// Descriptor comparisons per second of the Hamming kernels: the portable scalar path (what the
// x86 build ships: std::popcount at the baseline ISA), the same loop compiled with -mpopcnt
// (__builtin_popcountll, bench-only), and the build's active kernel (NEON on aarch64; under
// qemu-user its time means nothing, docs/evaluation.md). Prints figures; asserts nothing except
// that the variants agree before timing.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "simd/hamming.h"
#include "simd/hamming_popcnt.h"

namespace {

using zm::simd::BestTwo;
using zm::simd::kHammingBytes;

std::vector<std::uint8_t> Random(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<std::uint8_t> d(n * kHammingBytes);
  for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
  return d;
}

template <void (*Fn)(const std::uint8_t*, const std::uint8_t*, std::size_t, std::uint16_t*)>
void BM_OneToMany(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto q = Random(1, 1);
  const auto t = Random(n, 2);
  std::vector<std::uint16_t> out(n);
  for (auto _ : state) {
    Fn(q.data(), t.data(), n, out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.counters["cmp_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * static_cast<double>(n),
                         benchmark::Counter::kIsRate);
}

template <void (*Fn)(const std::uint8_t*, std::size_t, const std::uint8_t*, std::size_t, BestTwo*)>
void BM_BestTwo(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));  // n queries x n trains
  const auto q = Random(n, 3);
  const auto t = Random(n, 4);
  std::vector<BestTwo> out(n);
  for (auto _ : state) {
    Fn(q.data(), n, t.data(), n, out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.counters["cmp_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * static_cast<double>(n * n),
                         benchmark::Counter::kIsRate);
}

BENCHMARK(BM_OneToMany<zm::simd::scalar::HammingOneToMany>)
    ->Name("one_to_many/scalar")
    ->Arg(500)
    ->Arg(4096);
BENCHMARK(BM_OneToMany<zm::simd::popcnt::HammingOneToMany>)
    ->Name("one_to_many/popcnt")
    ->Arg(500)
    ->Arg(4096);
BENCHMARK(BM_OneToMany<zm::simd::active::HammingOneToMany>)
    ->Name("one_to_many/active")
    ->Arg(500)
    ->Arg(4096);
BENCHMARK(BM_BestTwo<zm::simd::scalar::BestTwoMatches>)->Name("best_two/scalar")->Arg(500);
BENCHMARK(BM_BestTwo<zm::simd::popcnt::BestTwoMatches>)->Name("best_two/popcnt")->Arg(500);
BENCHMARK(BM_BestTwo<zm::simd::active::BestTwoMatches>)->Name("best_two/active")->Arg(500);

// The variants must agree before their speeds are compared.
bool VariantsAgree() {
  const auto q = Random(64, 5);
  const auto t = Random(333, 6);
  std::vector<BestTwo> a(64), b(64), c(64);
  zm::simd::scalar::BestTwoMatches(q.data(), 64, t.data(), 333, a.data());
  zm::simd::popcnt::BestTwoMatches(q.data(), 64, t.data(), 333, b.data());
  zm::simd::active::BestTwoMatches(q.data(), 64, t.data(), 333, c.data());
  for (std::size_t i = 0; i < 64; ++i) {
    if (a[i].best_index != b[i].best_index || a[i].best_distance != b[i].best_distance ||
        a[i].second_distance != b[i].second_distance || a[i].best_index != c[i].best_index ||
        a[i].second_distance != c[i].second_distance) {
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (!VariantsAgree()) {
    std::fprintf(stderr, "hamming_bench: kernels disagree; not timing\n");
    return 1;
  }
  std::printf("active kernel: %s; popcnt variant: %s\n", zm::simd::ActiveHammingKernel(),
              zm::simd::popcnt::KernelName());
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
