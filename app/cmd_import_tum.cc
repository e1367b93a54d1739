// `zonemap import-tum DIR --poses FILE --out MAP.db`: a zonemap map from a TUM RGB-D folder at
// given keyframe poses (lib/import/tum_import.h): ORB features from the one extractor, dense
// JPEG + RVL payloads, odometry links, zones from keyframe positions, the vocabulary. The output
// appears only when complete (written as MAP.db.tmp, then renamed).
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "import/tum_import.h"
#include "report_json.h"

namespace zm::app {
namespace {

void DrawProgress(std::string_view stage, std::uint64_t done, std::uint64_t total) {
  std::fprintf(stderr, "\r%.*s %llu/%llu", static_cast<int>(stage.size()), stage.data(),
               static_cast<unsigned long long>(done), static_cast<unsigned long long>(total));
  if (done == total) std::fputc('\n', stderr);
  std::fflush(stderr);
}

nlohmann::json ToJson(const TumImportReport& r, const std::string& out) {
  nlohmann::json vocabulary = nullptr;
  if (r.vocabulary_trained) {
    vocabulary = {{"words", r.vocabulary.words},
                  {"nodes", r.vocabulary.nodes},
                  {"memory_bytes", r.vocabulary.memory_bytes},
                  {"training_keyframes", r.vocabulary.training_keyframes},
                  {"training_descriptors", r.vocabulary.training_descriptors},
                  {"train_ms", r.vocabulary.train_ms}};
  }
  return {{"output", out},
          {"listing", r.listing},
          {"colour_entries", r.colour_entries},
          {"frames", r.frames},
          {"gaps", r.gaps},
          {"malformed_lines", r.malformed_lines},
          {"poses", r.poses},
          {"frames_without_pose", r.frames_without_pose},
          {"refused", r.refused},
          {"keyframes", r.keyframes},
          {"features", r.features},
          {"features_with_point", r.features_with_point},
          {"links", r.links},
          {"zones", r.zones},
          {"total_payload_bytes", r.total_payload_bytes},
          {"largest_resident_bytes", r.largest_resident_bytes},
          {"camera", CameraJson(r.camera)},
          {"vocabulary", vocabulary},
          {"problems", r.problems},
          {"extract_ms", r.extract_ms},
          {"ms", r.ms}};
}

}  // namespace

void AddImportTumCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string dir, poses, out;
    TumImportOptions o;
    bool no_vocabulary = false;
    bool json = false;
    bool quiet = false;
  };
  auto opts = std::make_shared<Opts>();
  TumImportOptions& o = opts->o;
  auto* cmd = app.add_subcommand(
      "import-tum", "Build a zonemap map from a TUM RGB-D folder at given keyframe poses");
  cmd->add_option("DIR", opts->dir, "TUM RGB-D folder (rgb.txt + depth.txt, or associations.txt)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--poses", opts->poses,
                  "TUM trajectory 'stamp tx ty tz qx qy qz qw' of the colour camera (groundtruth.txt "
                  "or any estimate)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", opts->out, "zonemap map database to create")->required();
  cmd->add_flag("--overwrite", o.overwrite, "replace OUT if it exists (only once the import succeeded)");
  cmd->add_option("--fx", o.folder.camera.fx, "focal length x, pixels (freiburg1)")->capture_default_str();
  cmd->add_option("--fy", o.folder.camera.fy, "focal length y, pixels")->capture_default_str();
  cmd->add_option("--cx", o.folder.camera.cx, "principal point x, pixels")->capture_default_str();
  cmd->add_option("--cy", o.folder.camera.cy, "principal point y, pixels")->capture_default_str();
  cmd->add_option("--width", o.folder.camera.width, "image width, pixels")->capture_default_str();
  cmd->add_option("--height", o.folder.camera.height, "image height, pixels")->capture_default_str();
  cmd->add_option("--depth-scale", o.folder.depth_units_per_m, "depth PNG units per metre")
      ->capture_default_str();
  cmd->add_option("--max-dt", o.folder.max_stamp_difference_s,
                  "colour-depth association tolerance, seconds")
      ->capture_default_str();
  cmd->add_option("--pose-max-dt", o.max_pose_difference_s, "frame-pose association tolerance, seconds")
      ->capture_default_str();
  cmd->add_option("--keyframe-distance", o.keyframe_distance_m,
                  "a new keyframe after this much motion, metres")
      ->capture_default_str();
  cmd->add_option("--keyframe-angle", o.keyframe_angle_deg,
                  "... or this much rotation, degrees")
      ->capture_default_str();
  cmd->add_option("--max-features", o.orb.max_features, "ORB features kept per keyframe (Vis/MaxFeatures)")
      ->capture_default_str();
  cmd->add_option("--word-features", o.orb.word_features,
                  "the strongest of them quantized into words (Kp/MaxFeatures)")
      ->capture_default_str();
  cmd->add_option("--zone-cell", o.zone_cell_m, "zones: square cells of this size, metres")
      ->capture_default_str();
  cmd->add_flag("--no-vocabulary", opts->no_vocabulary,
                "do not train the vocabulary (train it later with `zonemap vocab`)");
  cmd->add_flag("--json", opts->json, "print the import report as JSON");
  cmd->add_flag("-q,--quiet", opts->quiet, "no progress");
  cmd->callback([opts, &ctx] {
    TumImportOptions& io = opts->o;
    io.train_vocabulary = !opts->no_vocabulary;
    io.vocabulary.word_features = io.orb.word_features;
    if (!opts->quiet && isatty(STDERR_FILENO) != 0) io.progress = DrawProgress;
    auto r = ImportTum(opts->dir, opts->poses, opts->out, io);
    if (!r.ok()) {
      ctx.Fail("import-tum", r.status());
      return;
    }
    // Every refused input and gap: one line each on stderr.
    for (const std::string& p : r->problems) std::fprintf(stderr, "import-tum: %s\n", p.c_str());
    if (opts->json) {
      std::printf("%s\n", ToJson(*r, opts->out).dump(2).c_str());
      return;
    }
    std::printf("import-tum: %s (%s) -> %s in %.1f ms\n", opts->dir.c_str(), r->listing.c_str(),
                opts->out.c_str(), r->ms);
    std::printf("  frames %u associated of %u colour (%u gaps, %u malformed lines), %u without a "
                "pose of %u, %u refused\n",
                r->frames, r->colour_entries, r->gaps, r->malformed_lines, r->frames_without_pose,
                r->poses, r->refused);
    std::printf("  keyframes %u, features %llu (%llu with depth), %.2f ms ORB per keyframe\n",
                r->keyframes, static_cast<unsigned long long>(r->features),
                static_cast<unsigned long long>(r->features_with_point),
                r->keyframes > 0 ? r->extract_ms / r->keyframes : 0.0);
    std::printf("  links %u, zones %u, payloads %.2f MB, largest keyframe %u bytes in a slot\n",
                r->links, r->zones, static_cast<double>(r->total_payload_bytes) / 1e6,
                r->largest_resident_bytes);
    if (r->vocabulary_trained) {
      std::printf("  vocabulary %u words, %u nodes from %llu descriptors, %.2f MB\n",
                  r->vocabulary.words, r->vocabulary.nodes,
                  static_cast<unsigned long long>(r->vocabulary.training_descriptors),
                  static_cast<double>(r->vocabulary.memory_bytes) / 1e6);
    }
  });
}

}  // namespace zm::app
