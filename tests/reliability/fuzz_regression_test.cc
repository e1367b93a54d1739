// Replays every input kept in fuzz/regressions/<target>/ (crashes the fuzzers once found, now
// fixed) and every seed in fuzz/corpus/<target>/ through the fuzz targets' own harnesses, which
// are compiled into this test with their entry point renamed (tests/reliability/CMakeLists.txt).
// A harness aborts on any broken invariant, and the ASan/UBSan build catches the rest, so a
// regression fails here in every `make test`, without clang or libFuzzer.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int ZmFuzzZoneFile(const std::uint8_t* data, std::size_t size);
extern "C" int ZmFuzzPayload(const std::uint8_t* data, std::size_t size);
extern "C" int ZmFuzzDenseCodec(const std::uint8_t* data, std::size_t size);
extern "C" int ZmFuzzPngDecoder(const std::uint8_t* data, std::size_t size);
extern "C" int ZmFuzzRtabmapBlob(const std::uint8_t* data, std::size_t size);
extern "C" int ZmFuzzLineProtocol(const std::uint8_t* data, std::size_t size);

namespace zm {
namespace {

using FuzzFn = int (*)(const std::uint8_t*, std::size_t);

// Feeds every file of fuzz/<kind>/<target>/ to `fn`; returns how many.
int Replay(const std::string& kind, const std::string& target, FuzzFn fn) {
  const std::filesystem::path dir = std::filesystem::path(ZM_SOURCE_DIR) / "fuzz" / kind / target;
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) return 0;
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.is_regular_file()) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    INFO(f.string());
    std::ifstream in(f, std::ios::binary);
    const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    // An exact-size heap copy, so a read one past the end is an ASan error here too.
    std::vector<std::uint8_t> data(bytes.begin(), bytes.end());
    CHECK(fn(data.data(), data.size()) == 0);
  }
  return static_cast<int>(files.size());
}

void ReplayTarget(const std::string& target, FuzzFn fn) {
  const int seeds = Replay("corpus", target, fn);
  const int regressions = Replay("regressions", target, fn);
  MESSAGE(target << ": " << seeds << " seeds, " << regressions << " regression inputs");
  CHECK(seeds > 0);
}

TEST_CASE("fuzz regressions: zone file parser") { ReplayTarget("zone_file", ZmFuzzZoneFile); }
TEST_CASE("fuzz regressions: keyframe payload decoder") { ReplayTarget("payload", ZmFuzzPayload); }
TEST_CASE("fuzz regressions: dense keyframe decoder") { ReplayTarget("dense_codec", ZmFuzzDenseCodec); }
TEST_CASE("fuzz regressions: PNG frame decoder") { ReplayTarget("png_decoder", ZmFuzzPngDecoder); }
TEST_CASE("fuzz regressions: RTAB-Map blob decoders") { ReplayTarget("rtabmap_blob", ZmFuzzRtabmapBlob); }
TEST_CASE("fuzz regressions: line protocol") { ReplayTarget("line_protocol", ZmFuzzLineProtocol); }

}  // namespace
}  // namespace zm
