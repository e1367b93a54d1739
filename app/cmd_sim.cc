// `zonemap sim hospital|floorplan`: generate a scenario folder (map.db, zones.geojson, map.pgm/
// map.yaml, mapping_gt.tum, localization_gt.tum, frames.bin, route.json, scenario.json) from a
// generated hospital or a real floor plan. Deterministic from --seed; progress on stderr.
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "commands.h"
#include "sim/building.h"
#include "sim/scenario.h"

namespace zm::app {
namespace {

struct SimOpts {
  sim::ScenarioOptions scenario;
  std::string out;
  std::string dense = "640x480";
  std::string depth_noise;  // A,B,C
  std::string image = "640x480";
  std::string decor = "repeated";
  std::string features = "orb";  // the oracle only by name (issue 26)
  double hfov_deg = 90.0;
  bool quiet = false;
  // hospital
  sim::HospitalOptions hospital;
  // floorplan
  sim::FloorplanOptions floorplan;
};

bool ParsePair(const std::string& text, char sep, std::uint64_t* a, std::uint64_t* b) {
  const auto pos = text.find(sep);
  if (pos == std::string::npos) return false;
  try {
    std::size_t used = 0;
    *a = std::stoull(text.substr(0, pos), &used);
    if (used != pos) return false;
    const std::string rest = text.substr(pos + 1);
    *b = std::stoull(rest, &used);
    return used == rest.size();
  } catch (const std::exception&) {
    return false;
  }
}

void AddScenarioOptions(CLI::App* cmd, SimOpts* o) {
  auto& s = o->scenario;
  cmd->add_option("--seed", s.seed, "random seed (everything is deterministic from it)")->capture_default_str();
  cmd->add_option("--out", o->out, "output folder")->required();
  cmd->add_option("--dense", o->dense, "dense RGB-D resolution WxH at footprint scale 1")->capture_default_str();
  cmd->add_option("--footprint-scale", s.dense.footprint_scale,
                  "(0, 1]: scale each keyframe's resident footprint by this (the dense resolution by ~its root)")
      ->capture_default_str();
  cmd->add_option("--cloud-step", s.dense.cloud_step, "decimation of the resident point cloud (0 = none)")
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", s.dense.jpeg_quality, "JPEG quality of the colour images")->capture_default_str();
  cmd->add_option("--depth-noise", o->depth_noise, "depth sigma A,B,C in metres: A + B z + C z^2");
  cmd->add_option("--image", o->image, "camera resolution WxH (keypoints)")->capture_default_str();
  cmd->add_option("--hfov", o->hfov_deg, "camera horizontal field of view, degrees")->capture_default_str();
  cmd->add_option("--range", s.camera.range_m, "landmark observation range, metres")->capture_default_str();
  cmd->add_option("--max-features", s.noise.max_features, "features per keyframe or frame")->capture_default_str();
  cmd->add_option("--bit-flip", s.noise.bit_flip_probability, "descriptor bit-flip probability")->capture_default_str();
  cmd->add_option("--pixel-noise", s.noise.pixel_sigma, "keypoint noise sigma, pixels")->capture_default_str();
  cmd->add_option("--outliers", s.noise.outlier_ratio, "outlier features per inlier")->capture_default_str();
  cmd->add_option("--landmark-density", s.landmarks.wall_density_per_m2, "landmarks per m2 of wall")->capture_default_str();
  cmd->add_option("--keyframe-distance", s.keyframe_distance_m, "metres between keyframes")->capture_default_str();
  cmd->add_option("--keyframe-angle", s.keyframe_angle_deg, "degrees between keyframes")->capture_default_str();
  cmd->add_option("--rate", s.rate_hz, "localization frames per second")->capture_default_str();
  cmd->add_option("--tasks", s.tasks, "patrol tasks (go to room X, with revisits)")->capture_default_str();
  cmd->add_option("--revisit", s.revisit_probability, "probability a task revisits a room")->capture_default_str();
  cmd->add_option("--speed", s.motion.speed_mps, "robot speed, m/s")->capture_default_str();
  cmd->add_option("--odom-trans-noise", s.drift.trans_noise_per_m, "odometry translation noise per metre")->capture_default_str();
  cmd->add_option("--odom-trans-bias", s.drift.trans_bias, "odometry scale bias")->capture_default_str();
  cmd->add_option("--odom-heading-noise", s.drift.heading_noise_deg_per_m, "heading noise, deg per metre")->capture_default_str();
  cmd->add_option("--odom-heading-bias", s.drift.heading_bias_deg_per_m, "heading bias, deg per metre")->capture_default_str();
  cmd->add_option("--threads", s.threads, "worker threads (output does not depend on it)")->capture_default_str();
  cmd->add_option("--features", o->features,
                  "where features come from: orb (from rendered pixels: keyframes at mapping, "
                  "frames in the loop; textured look, a vocabulary in the map) or oracle (each "
                  "landmark's own descriptor, for comparison)")
      ->check(CLI::IsMember({"orb", "oracle"}))
      ->capture_default_str();
  cmd->add_option("--orb-features", s.orb.max_features, "orb: features kept per image (Vis/MaxFeatures)")
      ->capture_default_str();
  cmd->add_option("--lighting-spread", s.lighting.gain_spread,
                  "orb: the localization run's gain differs from the mapping run's by up to this")
      ->capture_default_str();
  cmd->add_option("--exposure", s.lighting.exposure_s,
                  "orb: exposure time for motion blur, seconds (0: no blur)")
      ->capture_default_str();
  cmd->add_option("--decor-seed", s.dense.decor_seed, "orb: the building's décor")->capture_default_str();
  cmd->add_option("--decor", o->decor,
                  "orb: repeated (posters and signs from small catalogues: places look alike, as "
                  "in a hospital) or unique (every poster and sign its own design)")
      ->check(CLI::IsMember({"repeated", "unique"}))
      ->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "no progress bar");
}

// Applies the string options; returns an error message or "".
std::string Finalize(SimOpts* o, const std::string& source) {
  auto& s = o->scenario;
  std::uint64_t w = 0, h = 0;
  if (!ParsePair(o->image, 'x', &w, &h) || w < 16 || h < 16 || w > 8192 || h > 8192) {
    return "--image " + o->image + " is not WxH within [16, 8192]";
  }
  if (!(o->hfov_deg > 10.0 && o->hfov_deg < 170.0)) return "--hfov must be in (10, 170) degrees";
  s.camera.intrinsics = sim::MakeIntrinsics(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h), o->hfov_deg);
  s.hfov_deg = o->hfov_deg;
  if (!ParsePair(o->dense, 'x', &w, &h) || w < 8 || h < 8 || w > 4096 || h > 4096) {
    return "--dense " + o->dense + " is not WxH within [8, 4096]";
  }
  s.dense.width = static_cast<std::uint32_t>(w);
  s.dense.height = static_cast<std::uint32_t>(h);
  if (!o->depth_noise.empty()) {
    double a = 0, b = 0, c = 0;
    char tail = 0;
    if (std::sscanf(o->depth_noise.c_str(), "%lf,%lf,%lf%c", &a, &b, &c, &tail) != 3) {
      return "--depth-noise " + o->depth_noise + " is not A,B,C (metres: sigma = A + B z + C z^2)";
    }
    s.dense.depth_sigma_m = a;
    s.dense.depth_sigma_per_m = b;
    s.dense.depth_sigma_per_m2 = c;
  }
  if (Status st = sim::ValidateDenseOptions(s.dense); !st.ok()) return st.message();
  if (!(s.camera.range_m > 0.5 && s.camera.range_m <= 50.0)) return "--range must be in (0.5, 50] metres";
  if (!(s.motion.speed_mps > 0.05 && s.motion.speed_mps <= 5.0)) return "--speed must be in (0.05, 5] m/s";
  if (!(s.keyframe_distance_m > 0.01) || !(s.keyframe_angle_deg > 0.1)) {
    return "--keyframe-distance and --keyframe-angle must be positive";
  }
  if (s.threads < 1 || s.threads > 64) return "--threads must be in [1, 64]";
  s.features = o->features == "orb" ? sim::FeatureSource::kOrb : sim::FeatureSource::kOracle;
  s.dense.repeated_decor = o->decor == "repeated";
  if (!(s.lighting.gain_spread >= 0.0 && s.lighting.gain_spread < 0.9)) {
    return "--lighting-spread must be in [0, 0.9)";
  }
  if (!(s.lighting.exposure_s >= 0.0 && s.lighting.exposure_s <= 0.2)) {
    return "--exposure must be in [0, 0.2] seconds";
  }
  s.progress = !o->quiet;
  s.source = source;
  return "";
}

void Run(const sim::Building& building, SimOpts* o, const char* name, CommandContext& ctx,
         double build_s) {
  const auto t0 = std::chrono::steady_clock::now();
  auto report = sim::WriteScenario(building, o->scenario, o->out);
  if (!report.ok()) {
    ctx.Fail(name, report.status());
    return;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const sim::ScenarioReport& r = *report;
  std::printf("sim %s: %s\n", name, o->out.c_str());
  std::printf("  building   %.0f m2, %zu floor(s), %llu zones (%llu unreachable), %llu landmarks\n",
              building.area_m2, building.floors.size(), static_cast<unsigned long long>(r.zones),
              static_cast<unsigned long long>(r.unreachable_zones), static_cast<unsigned long long>(r.landmarks));
  std::printf("  mapping    %llu keyframes over %.0f m, %llu features/keyframe on average\n",
              static_cast<unsigned long long>(r.keyframes), r.mapping_length_m,
              static_cast<unsigned long long>(r.mean_features_per_keyframe));
  std::printf("  dense      %ux%u RGB-D (JPEG q%d + RVL), cloud step %u, footprint scale %g\n",
              r.dense_width, r.dense_height, o->scenario.dense.jpeg_quality, o->scenario.dense.cloud_step,
              o->scenario.dense.footprint_scale);
  std::printf("  keyframe   on disk min %u median %u max %u (mean %.0f) bytes\n", r.keyframe_bytes_min,
              r.keyframe_bytes_median, r.keyframe_bytes_max, r.keyframe_bytes_mean);
  std::printf("  keyframe   resident min %u median %u max %u (mean %.0f) bytes\n", r.resident_bytes_min,
              r.resident_bytes_median, r.resident_bytes_max, r.resident_bytes_mean);
  std::printf("  patrol     %llu tasks, %llu frames over %.0f m / %.0f s, %llu features/frame\n",
              static_cast<unsigned long long>(r.tasks), static_cast<unsigned long long>(r.frames),
              r.localization_length_m, r.localization_duration_s,
              static_cast<unsigned long long>(r.mean_features_per_frame));
  if (o->scenario.features == sim::FeatureSource::kOrb) {
    std::printf("  frames     %ux%u JPEG, %u bytes on average, %.1f frames/s rendered and encoded "
                "(%d threads); lighting gain %.2f offset %+.1f\n",
                r.dense_width, r.dense_height, r.frame_jpeg_bytes_mean,
                r.frames_s > 0.0 ? static_cast<double>(r.frames) / r.frames_s : 0.0,
                o->scenario.threads, r.lighting_gain, r.lighting_offset);
    std::printf("  vocabulary %u words, %llu bytes, trained in %.2f s\n", r.vocabulary_words,
                static_cast<unsigned long long>(r.vocabulary_bytes), r.vocabulary_s);
  }
  std::printf("  time       %.2f s building + %.2f s scenario, of which %.2f s keyframes (%d threads)\n",
              build_s, s, r.keyframes_s, o->scenario.threads);
}

}  // namespace

void AddSimCommand(CLI::App& app, CommandContext& ctx) {
  CLI::App* sim_cmd = GetOrAddSubcommand(app, "sim", "Generate simulated scenarios (hospital, real floor plans)");

  auto ho = std::make_shared<SimOpts>();
  auto* hosp = sim_cmd->add_subcommand("hospital", "A generated hospital-like building");
  hosp->add_option("--area", ho->hospital.area_m2, "footprint of one floor, m2 [300, 200000]")->capture_default_str();
  hosp->add_option("--floors", ho->hospital.floors, "floors (joined by an elevator)")->capture_default_str();
  hosp->add_option("--resolution", ho->hospital.resolution_m, "grid cell, metres [0.02, 0.2]")->capture_default_str();
  hosp->add_option("--ward-probability", ho->hospital.ward_probability, "share of room columns that are wards")->capture_default_str();
  AddScenarioOptions(hosp, ho.get());
  hosp->callback([ho, &ctx] {
    ho->hospital.seed = ho->scenario.seed;
    char source[160];
    std::snprintf(source, sizeof(source), "sim hospital seed=%llu area=%.0f floors=%d",
                  static_cast<unsigned long long>(ho->scenario.seed), ho->hospital.area_m2, ho->hospital.floors);
    if (std::string err = Finalize(ho.get(), source); !err.empty()) {
      ctx.Fail("sim hospital", err);
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    auto building = sim::GenerateHospital(ho->hospital);
    if (!building.ok()) {
      ctx.Fail("sim hospital", building.status());
      return;
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    Run(*building, ho.get(), "hospital", ctx, s);
  });

  auto fo = std::make_shared<SimOpts>();
  auto* fp = sim_cmd->add_subcommand("floorplan", "A real occupancy image (white free, black occupied)");
  fp->add_option("map", fo->floorplan.map_path, "occupancy PNG")->required()->check(CLI::ExistingFile);
  fp->add_option("--gt", fo->floorplan.gt_path, "ground-truth rooms PNG (one flat colour per room)")
      ->check(CLI::ExistingFile);
  fp->add_option("--resolution", fo->floorplan.resolution_m, "metres per pixel")->capture_default_str();
  AddScenarioOptions(fp, fo.get());
  fp->callback([fo, &ctx] {
    const std::string source = "sim floorplan " + fo->floorplan.map_path + " seed=" + std::to_string(fo->scenario.seed);
    if (std::string err = Finalize(fo.get(), source); !err.empty()) {
      ctx.Fail("sim floorplan", err);
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    auto building = sim::ImportFloorplan(fo->floorplan);
    if (!building.ok()) {
      ctx.Fail("sim floorplan", building.status());
      return;
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    Run(*building, fo.get(), "floorplan", ctx, s);
  });
}

}  // namespace zm::app
