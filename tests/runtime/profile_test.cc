// Profiles: every shipped profile loads; unknown keys, wrong types and bad values are errors
// naming the file and the key; byte sizes, --memory-thr and overrides parse as documented.
#include "runtime/profile.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;

const std::string kProfilesDir = ZM_SOURCE_DIR "/profiles";

Status ParseError(const std::string& toml) {
  Result<Profile> p = ParseProfile(toml, "bad.toml");
  REQUIRE_FALSE(p.ok());
  return p.status();
}

ProfileOverrides Overrides(std::optional<std::string> policy,
                           std::optional<std::string> memory_thr) {
  ProfileOverrides o;
  o.policy = std::move(policy);
  o.memory_thr = std::move(memory_thr);
  return o;
}

TEST_CASE("every shipped profile loads, by path and by name") {
  int loaded = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kProfilesDir)) {
    if (entry.path().extension() != ".toml") continue;
    CAPTURE(entry.path().string());
    Result<Profile> by_path = LoadProfile(entry.path().string());
    REQUIRE_MESSAGE(by_path.ok(), by_path.status().ToString());
    Result<Profile> by_name = LoadProfile(entry.path().stem().string());
    REQUIRE_MESSAGE(by_name.ok(), by_name.status().ToString());
    CHECK(by_name->device.memory_bytes == by_path->device.memory_bytes);
    CHECK(by_path->device.memory_bytes > by_path->device.os_reserve_bytes);
    Result<std::uint64_t> share = MapShareBytes(*by_path);
    REQUIRE(share.ok());
    CHECK(*share > by_path->map.overhead_bytes);
    ++loaded;
  }
  CHECK(loaded >= 3);
}

TEST_CASE("orin-nano-8gb splits 8 GiB into OS, model, headroom and the map share") {
  Result<Profile> p = LoadProfile("orin-nano-8gb");
  REQUIRE_MESSAGE(p.ok(), p.status().ToString());
  CHECK(p->device.memory_bytes == 8ULL << 30);
  CHECK(p->policy.kind == PolicyKind::kSemantic);
  CHECK(p->policy.basic.max_retrieved == 2);
  CHECK(p->model.name == "qwen3-vl-2b");
  CHECK(p->model.weights_bytes == 1'900'000'000ULL);
  Result<std::uint64_t> share = MapShareBytes(*p);
  REQUIRE(share.ok());
  CHECK(*share ==
        (8ULL << 30) - p->device.os_reserve_bytes - 1'900'000'000ULL - p->map.headroom_bytes);
  Result<Profile> super = LoadProfile("orin-nano-8gb-super");
  REQUIRE(super.ok());
  CHECK(super->device.memory_bytes == p->device.memory_bytes);
  CHECK(*MapShareBytes(*super) == *share);
}

TEST_CASE("the profile fills the modules' own options, with their units") {
  Result<Profile> p = ParseProfile(
      "[policy]\nhysteresis_m = 0.75\n[policy.radius]\nmap_radius_m = 12.5\n"
      "[localization]\nmax_heading_deg = 45\nratio = 0.7\nransac_iterations = 42\n"
      "[loop]\nrate_hz = 2.5\ntelemetry_flush_ticks = 7\n"
      "[loads]\nsliced = false\ntick_ms = 1.5\ntick_bytes = \"4MiB\"\nidle_ms = 100\n"
      "idle_bytes = \"1GB\"\nmargin_ms = 8\n",
      "units.toml");
  REQUIRE_MESSAGE(p.ok(), p.status().ToString());
  CHECK(p->zones.hysteresis_m == doctest::Approx(0.75));
  CHECK(p->policy.radius.map_radius_m == doctest::Approx(12.5));
  CHECK(p->localizer.max_heading_diff_rad == doctest::Approx(M_PI / 4));
  CHECK(p->localizer.ratio == doctest::Approx(0.7f));
  CHECK(p->localizer.ransac_iterations == 42);
  CHECK(p->loop.rate_hz == doctest::Approx(2.5));
  CHECK(p->telemetry.flush_ticks == 7);
  CHECK_FALSE(p->loads.sliced);
  CHECK(p->loads.tick_ms == doctest::Approx(1.5));
  CHECK(p->loads.tick_bytes == 4ULL << 20);
  CHECK(p->loads.idle_ms == doctest::Approx(100.0));
  CHECK(p->loads.idle_bytes == 1'000'000'000ULL);
  CHECK(p->loads.margin_ms == doctest::Approx(8.0));
  // Absent keys keep the module's one default (no mirrored copies with other values).
  const Profile empty = *ParseProfile("", "empty.toml");
  CHECK(empty.policy.radius.map_radius_m == RadiusOptions{}.map_radius_m);
  CHECK(empty.policy.predictive.prefetch == PredictiveOptions{}.prefetch);
  CHECK(empty.loads.sliced == LoadSliceOptions{}.sliced);
  CHECK(empty.loads.tick_ms == LoadSliceOptions{}.tick_ms);
  CHECK(empty.loads.margin_ms == LoadSliceOptions{}.margin_ms);
  CHECK(empty.localizer.ransac_reprojection_px == LocalizerConfig{}.ransac_reprojection_px);
  CHECK(empty.zones.hysteresis_m == ZoneIndexOptions{}.hysteresis_m);
}

TEST_CASE("the core accepts the harness's sections without reading them") {
  // zonemapd reads the same files as the evaluation: [cotenant] belongs to the harness.
  CHECK(ParseProfile("[cotenant]\nprompt_tokens = 9\n", "co.toml").ok());
  // Keys that used to be parsed and then ignored are gone, so they are errors now.
  CHECK(
      Contains(ParseError("[policy.basic]\nstm_size = 10\n").message(), "'policy.basic.stm_size'"));
  CHECK(Contains(ParseError("[loop]\nrealtime = true\n").message(), "'loop.realtime'"));
  CHECK(Contains(ParseError("[device]\ncpu_max_ghz = 1.5\n").message(), "'device.cpu_max_ghz'"));
  // Predictive's own per-tick slice gave way to the working set's time slices ([loads]).
  CHECK(Contains(ParseError("[policy.predictive]\nmax_keyframes_per_tick = 64\n").message(),
                 "'policy.predictive.max_keyframes_per_tick'"));
  CHECK(Contains(ParseError("[loads]\ntick_ms = -1\n").message(), "'loads.tick_ms'"));
}

TEST_CASE("ZM_PROFILES_DIR is searched first and a missing profile names the search path") {
  const std::string dir = ZM_BINARY_DIR "/profile-test-dir";
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(kProfilesDir + "/host.toml", dir + "/only-here.toml",
                             std::filesystem::copy_options::overwrite_existing);
  setenv("ZM_PROFILES_DIR", dir.c_str(), 1);
  CHECK(LoadProfile("only-here").ok());
  unsetenv("ZM_PROFILES_DIR");
  Result<Profile> missing = LoadProfile("no-such-profile");
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().code() == StatusCode::kNotFound);
  CHECK(Contains(missing.status().message(), "no-such-profile"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("unknown keys are errors naming the file and the full key") {
  Status s = ParseError("[map]\nslot_byte = 3\n");
  CHECK(Contains(s.message(), "bad.toml"));
  CHECK(Contains(s.message(), "'map.slot_byte'"));
  CHECK(Contains(ParseError("[policy.basic]\nstm = 3\n").message(), "'policy.basic.stm'"));
  CHECK(Contains(ParseError("[gpu]\ncores = 1024\n").message(), "'gpu'"));
  CHECK(Contains(ParseError("colour = \"red\"\n").message(), "'colour'"));
}

TEST_CASE("wrong types and bad values are errors naming the key") {
  CHECK(Contains(ParseError("[map]\nslot_bytes = true\n").message(), "'map.slot_bytes'"));
  CHECK(Contains(ParseError("[map]\nlock_arena = 1\n").message(), "'map.lock_arena'"));
  // The device's swap: none or zram, and zram has a size.
  CHECK(Contains(ParseError("[device]\nswap = \"disk\"\n").message(), "'device.swap'"));
  CHECK(Contains(ParseError("[device]\nswap = \"zram\"\n").message(), "'device.swap_bytes'"));
  CHECK(Contains(ParseError("[device]\nswap_bytes = \"1GiB\"\n").message(), "'device.swap_bytes'"));
  CHECK(Contains(ParseError("[map]\nheadroom_bytes = \"3 parsecs\"\n").message(),
                 "'map.headroom_bytes'"));
  CHECK(Contains(ParseError("[map]\nmemory_thr_keyframes = -5\n").message(),
                 "'map.memory_thr_keyframes'"));
  CHECK(Contains(ParseError("[policy]\nname = \"greedy\"\n").message(), "'policy.name'"));
  CHECK(Contains(ParseError("[localization]\nratio = 1.5\n").message(), "'localization.ratio'"));
  CHECK(Contains(ParseError("[loop]\nrate_hz = 0\n").message(), "'loop.rate_hz'"));
  CHECK(Contains(ParseError("policy = 3\n").message(), "'policy'"));
  CHECK(Contains(ParseError("[map\n").message(), "bad.toml:1"));  // syntax error, with line
  // The memory split must add up.
  CHECK(Contains(
      ParseError("[device]\nmemory_bytes = \"4GiB\"\nos_reserve_bytes = \"5GiB\"\n").message(),
      "os_reserve_bytes"));
  CHECK(Contains(ParseError("[device]\nmemory_bytes = \"4GiB\"\nos_reserve_bytes = \"1GiB\"\n"
                            "[model]\nweights_bytes = \"3.3GB\"\n")
                     .message(),
                 "no map share left"));
}

TEST_CASE("an empty profile is all defaults with no byte limit") {
  Result<Profile> p = ParseProfile("", "empty.toml");
  REQUIRE(p.ok());
  CHECK(p->policy.kind == PolicyKind::kSemantic);
  CHECK(p->loop.rate_hz == 1.0);
  CHECK(*MapShareBytes(*p) == 0);
}

TEST_CASE("byte sizes: binary K/M/G and KiB/MiB/GiB, decimal KB/MB/GB") {
  CHECK(*ParseBytes("4096") == 4096);
  CHECK(*ParseBytes("4096B") == 4096);
  CHECK(*ParseBytes("2K") == 2048);
  CHECK(*ParseBytes("512MiB") == 512ULL << 20);
  CHECK(*ParseBytes("1.5GiB") == 3ULL << 29);
  CHECK(*ParseBytes("1.9GB") == 1'900'000'000ULL);
  CHECK(*ParseBytes("8G") == 8ULL << 30);
  CHECK_FALSE(ParseBytes("1.5").ok());
  CHECK_FALSE(ParseBytes("12 parsecs").ok());
  CHECK_FALSE(ParseBytes("").ok());
  CHECK_FALSE(ParseBytes("99999999999T").ok());
}

TEST_CASE("--memory-thr: a count, bytes, or both") {
  Result<MemoryThr> count = ParseMemoryThr("300");
  REQUIRE(count.ok());
  CHECK(*count->keyframes == 300);
  CHECK_FALSE(count->bytes.has_value());
  Result<MemoryThr> bytes = ParseMemoryThr("2GiB");
  REQUIRE(bytes.ok());
  CHECK(*bytes->bytes == 2ULL << 30);
  CHECK_FALSE(bytes->keyframes.has_value());
  Result<MemoryThr> both = ParseMemoryThr("300,512MiB");
  REQUIRE(both.ok());
  CHECK(*both->keyframes == 300);
  CHECK(*both->bytes == 512ULL << 20);
  CHECK_FALSE(ParseMemoryThr("0").ok());
  CHECK_FALSE(ParseMemoryThr("3,4").ok());
  CHECK_FALSE(ParseMemoryThr("lots").ok());
}

TEST_CASE("overrides replace profile values and K_max = min(count, bytes / slot)") {
  Result<Profile> loaded = LoadProfile("orin-nano-8gb");
  REQUIRE(loaded.ok());
  Profile p = *loaded;
  REQUIRE(ApplyOverrides(Overrides("basic", "300,1GiB"), p).ok());
  CHECK(p.policy.kind == PolicyKind::kBasic);
  CHECK(p.map.memory_thr_keyframes == 300);
  CHECK(p.map.map_share_bytes == 1ULL << 30);
  Result<Budget> b = DeriveBudget(p, 1 << 20, 5000);  // 1 MiB keyframes, 5,000 of them
  REQUIRE(b.ok());
  CHECK(b->keyframe_bytes == (1ULL << 30) - p.map.overhead_bytes);  // 768 slots of 1 MiB
  CHECK(b->k_max == 300);         // the count is the tighter limit
  CHECK(b->arena_slots == 5000);  // basic models RTAB-Map's growing heap

  REQUIRE(ApplyOverrides(Overrides("semantic", "5000"), p).ok());
  b = DeriveBudget(p, 1 << 20, 5000);
  REQUIRE(b.ok());
  CHECK(b->k_max == 768);  // now the bytes are
  CHECK(b->arena_slots == 768);

  CHECK_FALSE(ApplyOverrides(Overrides("greedy", {}), p).ok());
  CHECK_FALSE(
      DeriveBudget(p, 0, 5000).ok());  // slot size unknown: profile says 0, no keyframe size
}

}  // namespace
}  // namespace zm
