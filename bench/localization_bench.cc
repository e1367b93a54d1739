// The pixel front-end's costs (issue 26, first part), on this machine:
//   BM_OrbExtract     ms per 640x480 BGR frame + 16-bit depth (OrbExtractor, RTAB-Map's defaults:
//                     1000 features, 500 for words, scale 2, 3 levels);
//   BM_Quantize       ns per descriptor through a k = 10, L = 4 vocabulary;
//   BM_Transform      us per frame's bag of words (500 descriptors);
//   BM_Score/R        us per inverted-index query against R resident keyframes (100..3200), and
//                     at the end the least-squares slope in us per resident keyframe.
// Images: procedural texture (overlapping rectangles and discs of random grey on low-frequency
// noise, lightly blurred), deterministic from a seed; nothing photographic. The vocabulary is
// trained on the word features of 200 such images (one keyframe each); a resident keyframe's bag
// is 80 % of one training image's word features plus 20 % drawn from the others (revisits and
// aliasing), the queries are 20 held-out images. A figure, not a test.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "localization/inverted_index.h"
#include "localization/orb_extractor.h"
#include "localization/vocabulary.h"

namespace {

constexpr int kW = 640;
constexpr int kH = 480;
const zm::CameraIntrinsics kCamera{525.0, 525.0, 319.5, 239.5, kW, kH};
constexpr int kTrainImages = 200;
constexpr int kQueryImages = 20;
constexpr std::uint32_t kMaxResident = 3200;

cv::Mat TexturedBgr(std::uint32_t seed) {
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) {
    return lo + static_cast<int>(rng() % static_cast<unsigned>(hi - lo));
  };
  cv::Mat low(30, 40, CV_8UC3);
  cv::RNG noise(seed);  // not cv::randu: it draws from OpenCV's global generator
  noise.fill(low, cv::RNG::UNIFORM, cv::Scalar::all(60), cv::Scalar::all(200));
  cv::Mat img;
  cv::resize(low, img, cv::Size(kW, kH), 0, 0, cv::INTER_LINEAR);
  for (int i = 0; i < 300; ++i) {
    const cv::Point a(uni(0, kW), uni(0, kH));
    const cv::Point b(a.x + uni(4, 80), a.y + uni(4, 80));
    cv::rectangle(img, a, b, cv::Scalar(uni(0, 256), uni(0, 256), uni(0, 256)), cv::FILLED);
  }
  for (int i = 0; i < 150; ++i) {
    cv::circle(img, cv::Point(uni(0, kW), uni(0, kH)), uni(3, 30),
               cv::Scalar(uni(0, 256), uni(0, 256), uni(0, 256)), cv::FILLED);
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
  return img;
}

zm::OrbExtractor MakeExtractor() {
  auto e = zm::OrbExtractor::Create({}, kCamera);
  if (!e.ok()) {
    std::fprintf(stderr, "%s\n", e.status().ToString().c_str());
    std::exit(1);
  }
  return std::move(e).value();
}

// Word features (the strongest 500) of the training and query images, and the vocabulary.
struct Data {
  std::vector<std::vector<zm::Descriptor256>> train;  // per training image
  std::vector<std::vector<zm::Descriptor256>> query;  // per held-out image
  std::vector<zm::Vocabulary> vocabulary;             // one (Vocabulary has no default ctor)
};

const Data& GetData() {
  static const Data data = [] {
    Data d;
    zm::OrbExtractor extractor = MakeExtractor();
    zm::OrbFeatures out(1000);
    auto words_of = [&](std::uint32_t seed) {
      if (!extractor.Extract(TexturedBgr(seed), {}, &out).ok()) std::exit(1);
      return std::vector<zm::Descriptor256>(out.descriptors.begin(),
                                            out.descriptors.begin() + out.word_count);
    };
    std::vector<zm::Descriptor256> all;
    std::vector<std::uint32_t> sizes;
    for (int i = 0; i < kTrainImages; ++i) {
      d.train.push_back(words_of(static_cast<std::uint32_t>(i)));
      all.insert(all.end(), d.train.back().begin(), d.train.back().end());
      sizes.push_back(static_cast<std::uint32_t>(d.train.back().size()));
    }
    for (int i = 0; i < kQueryImages; ++i)
      d.query.push_back(words_of(100000u + static_cast<std::uint32_t>(i)));
    auto v = zm::Vocabulary::Train(all, sizes, {});
    if (!v.ok()) std::exit(1);
    d.vocabulary.push_back(std::move(v).value());
    std::printf(
        "vocabulary: k=%u L=%u, %u words, %u nodes, %zu bytes, trained on %zu descriptors "
        "of %d images\n",
        d.vocabulary[0].branching(), d.vocabulary[0].depth(), d.vocabulary[0].word_count(),
        d.vocabulary[0].node_count(), d.vocabulary[0].memory_bytes(), all.size(), kTrainImages);
    return d;
  }();
  return data;
}

void BM_OrbExtract(benchmark::State& state) {
  zm::OrbExtractor extractor = MakeExtractor();
  const cv::Mat bgr = TexturedBgr(7);
  const zm::DepthImage depth{cv::Mat(kH, kW, CV_16UC1, cv::Scalar(2500)), 1000.0};
  zm::OrbFeatures out(1000);
  for (auto _ : state) {
    if (!extractor.Extract(bgr, depth, &out).ok()) state.SkipWithError("extract failed");
    benchmark::DoNotOptimize(out.count);
  }
  state.counters["features"] = out.count;
}

void BM_Quantize(benchmark::State& state) {
  const Data& d = GetData();
  const std::vector<zm::Descriptor256>& q = d.query[0];
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(d.vocabulary[0].Quantize(q[i].data()));
    if (++i == q.size()) i = 0;
  }
}

void BM_Transform(benchmark::State& state) {
  const Data& d = GetData();
  zm::BowVector bag(1000);
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& q = d.query[i++ % d.query.size()];
    if (!d.vocabulary[0].Transform(q[0].data(), q.size(), &bag).ok()) state.SkipWithError("bag");
    benchmark::DoNotOptimize(bag.size());
  }
  state.counters["words"] = bag.size();
}

void BM_Score(benchmark::State& state) {
  const Data& d = GetData();
  const zm::Vocabulary& voc = d.vocabulary[0];
  const auto resident = static_cast<std::uint32_t>(state.range(0));
  zm::InvertedIndex index({voc.word_count(), kMaxResident, 500});
  std::mt19937 rng(26);
  zm::BowVector bag(1000);
  std::vector<zm::Descriptor256> kf;
  for (std::uint32_t r = 0; r < resident; ++r) {
    const auto& place = d.train[r % d.train.size()];
    kf.clear();
    for (const auto& desc : place) {
      kf.push_back(rng() % 5 != 0 ? desc : d.train[rng() % d.train.size()][rng() % 400]);
    }
    if (!voc.Transform(kf[0].data(), kf.size(), &bag).ok() ||
        !index.Add(zm::SlotIndex{r}, zm::KeyframeId{r + 1}, bag).ok()) {
      state.SkipWithError("add failed");
      return;
    }
  }
  std::vector<zm::BowVector> queries;
  for (const auto& q : d.query) {
    queries.emplace_back(1000);
    if (!voc.Transform(q[0].data(), q.size(), &queries.back()).ok()) std::exit(1);
  }
  std::vector<zm::IndexCandidate> out(10);
  std::size_t i = 0;
  std::uint64_t walked = 0;
  std::uint64_t calls = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(index.Score(queries[i++ % queries.size()], 10, out));
    walked += index.last_postings_walked();
    ++calls;
  }
  state.counters["resident"] = resident;
  state.counters["postings_per_query"] = static_cast<double>(walked) / static_cast<double>(calls);
  state.counters["index_MB"] = static_cast<double>(index.memory_bytes()) / 1e6;
}

BENCHMARK(BM_OrbExtract)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Quantize)->Unit(benchmark::kNanosecond);
BENCHMARK(BM_Transform)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Score)->Arg(100)->Arg(400)->Arg(1600)->Arg(3200)->Unit(benchmark::kMicrosecond);

// Console output as usual, and the (resident, CPU time) points of BM_Score for the slope: the
// median aggregate when the run is repeated (--benchmark_repetitions), else the single run.
class SlopeReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      auto it = run.counters.find("resident");
      if (run.run_name.function_name != "BM_Score" || it == run.counters.end()) continue;
      if (run.run_type == Run::RT_Aggregate && run.aggregate_name == "median") {
        median_[it->second.value] = run.GetAdjustedCPUTime();  // microseconds (the unit)
      } else if (run.run_type == Run::RT_Iteration) {
        single_[it->second.value] = run.GetAdjustedCPUTime();
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }
  const std::map<double, double>& points() const { return median_.empty() ? single_ : median_; }

 private:
  std::map<double, double> median_, single_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  SlopeReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  const auto& p = reporter.points();
  if (p.size() >= 2) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const auto& [x, y] : p) {
      sx += x;
      sy += y;
      sxx += x * x;
      sxy += x * y;
    }
    const double n = static_cast<double>(p.size());
    const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    std::printf(
        "Score: %.3f us per resident keyframe (least squares over %zu points), "
        "intercept %.1f us\n",
        slope, p.size(), (sy - slope * sx) / n);
  }
  benchmark::Shutdown();
  return 0;
}
