// `zonemap import-rtabmap IN.db OUT.db`: converts an RTAB-Map database (0.19 to 0.23) into a
// zonemap map database, keeping RTAB-Map's node ids. The output appears only when complete
// (written as OUT.db.tmp, then renamed). A progress bar goes to stderr when it is a terminal.
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "import/rtabmap_import.h"
#include "report_json.h"

namespace zm::app {
namespace {

// One self-overwriting line on stderr: "nodes [#########.....]  1234/2000".
void DrawProgress(std::string_view stage, std::uint64_t done, std::uint64_t total) {
  constexpr int kWidth = 30;
  const double f = total == 0 ? 1.0 : static_cast<double>(done) / static_cast<double>(total);
  const int filled = static_cast<int>(f * kWidth);
  std::string bar(static_cast<std::size_t>(filled), '#');
  bar.append(static_cast<std::size_t>(kWidth - filled), '.');
  std::fprintf(stderr, "\r%-6.*s [%s] %llu/%llu", static_cast<int>(stage.size()), stage.data(),
               bar.c_str(), static_cast<unsigned long long>(done),
               static_cast<unsigned long long>(total));
  if (done == total) std::fputc('\n', stderr);
  std::fflush(stderr);
}

nlohmann::json ToJson(const RtabmapImportReport& r, const std::string& out) {
  return {{"output", out},
          {"rtabmap_version", r.rtabmap_version},
          {"nodes", r.nodes},
          {"keyframes", r.keyframes},
          {"skipped_invalid", r.skipped_invalid},
          {"skipped_null_pose", r.skipped_null_pose},
          {"optimized_poses", r.optimized_poses},
          {"link_rows", r.link_rows},
          {"links", r.links},
          {"links_duplicate", r.links_duplicate},
          {"links_self", r.links_self},
          {"links_landmark", r.links_landmark},
          {"links_dangling", r.links_dangling},
          {"features", r.features},
          {"features_skipped", r.features_skipped},
          {"images", r.images},
          {"depths", r.depths},
          {"stereo_right_dropped", r.stereo_right_dropped},
          {"largest_payload_bytes", r.largest_payload_bytes},
          {"total_payload_bytes", r.total_payload_bytes},
          {"camera", r.has_camera ? CameraJson(r.camera) : nlohmann::json(nullptr)},
          {"last_working_memory", r.last_wm_recorded
                                      ? nlohmann::json{{"nodes", r.last_wm_nodes},
                                                       {"info_time_enter", r.last_info_time_enter}}
                                      : nlohmann::json(nullptr)},
          {"features_source",
           r.orb_keyframes > 0 || r.orb_nodes_without_images > 0 ? "orb" : "rtabmap"},
          {"orb_keyframes", r.orb_keyframes},
          {"orb_nodes_without_images", r.orb_nodes_without_images},
          {"extract_ms", r.extract_ms},
          {"vocabulary",
           r.vocabulary_trained
               ? nlohmann::json{{"words", r.vocabulary.words},
                                {"nodes", r.vocabulary.nodes},
                                {"memory_bytes", r.vocabulary.memory_bytes},
                                {"training_descriptors", r.vocabulary.training_descriptors}}
               : nlohmann::json(nullptr)},
          {"ms", r.ms}};
}

}  // namespace

void AddImportCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string in, out;
    bool overwrite = false;
    bool no_dense = false;
    bool raw_poses = false;
    bool json = false;
    bool quiet = false;
    std::string features = "rtabmap";
  };
  auto opts = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("import-rtabmap",
                                 "Convert an RTAB-Map database (0.19-0.23) into a zonemap map database");
  cmd->add_option("IN", opts->in, "RTAB-Map database (read only)")->required()->check(CLI::ExistingFile);
  cmd->add_option("OUT", opts->out, "zonemap map database to create")->required();
  cmd->add_flag("--overwrite", opts->overwrite, "replace OUT if it exists (only once the import succeeded)");
  cmd->add_flag("--no-dense", opts->no_dense, "leave colour and depth images out of the payloads");
  cmd->add_flag("--raw-poses", opts->raw_poses, "use Node.pose (odometry) even when Admin.opt_poses exists");
  cmd->add_option("--features", opts->features,
                  "where keyframe features come from. rtabmap (default): RTAB-Map's own Feature "
                  "rows, exactly, with no image decoding (a database without images keeps its "
                  "features). orb: zonemap's one ORB extractor on each node's Data image and "
                  "depth, as its loop and import-tum extract them, then the vocabulary is trained "
                  "and stored (what a map localized by zonemap's pixel loop needs)")
      ->check(CLI::IsMember({"rtabmap", "orb"}))
      ->capture_default_str();
  cmd->add_flag("--json", opts->json, "print the import report as JSON");
  cmd->add_flag("-q,--quiet", opts->quiet, "no progress bar");
  cmd->callback([opts, &ctx] {
    RtabmapImportOptions o;
    o.features = opts->features == "orb" ? RtabmapFeatureSource::kOrb : RtabmapFeatureSource::kRtabmap;
    o.overwrite = opts->overwrite;
    o.keep_dense = !opts->no_dense;
    o.use_optimized_poses = !opts->raw_poses;
    if (!opts->quiet && isatty(STDERR_FILENO) != 0) o.progress = DrawProgress;
    auto r = ImportRtabmap(opts->in, opts->out, o);
    if (!r.ok()) {
      ctx.Fail("import-rtabmap", r.status());
      return;
    }
    if (opts->json) {
      std::printf("%s\n", ToJson(*r, opts->out).dump(2).c_str());
      return;
    }
    std::printf("import-rtabmap: %s (RTAB-Map %s) -> %s in %.1f ms\n", opts->in.c_str(),
                r->rtabmap_version.empty() ? "?" : r->rtabmap_version.c_str(), opts->out.c_str(), r->ms);
    std::printf("  keyframes %llu of %llu nodes (%llu invalid, %llu without pose), %llu with optimized poses\n",
                static_cast<unsigned long long>(r->keyframes), static_cast<unsigned long long>(r->nodes),
                static_cast<unsigned long long>(r->skipped_invalid),
                static_cast<unsigned long long>(r->skipped_null_pose),
                static_cast<unsigned long long>(r->optimized_poses));
    std::printf("  links %llu from %llu rows (%llu duplicates, %llu self, %llu landmark, %llu dangling)\n",
                static_cast<unsigned long long>(r->links), static_cast<unsigned long long>(r->link_rows),
                static_cast<unsigned long long>(r->links_duplicate),
                static_cast<unsigned long long>(r->links_self),
                static_cast<unsigned long long>(r->links_landmark),
                static_cast<unsigned long long>(r->links_dangling));
    std::printf("  features %llu (%llu skipped), images %llu, depths %llu\n",
                static_cast<unsigned long long>(r->features),
                static_cast<unsigned long long>(r->features_skipped),
                static_cast<unsigned long long>(r->images), static_cast<unsigned long long>(r->depths));
    std::printf("  payloads %.2f MiB, largest %u bytes (the minimum slot_bytes)\n",
                static_cast<double>(r->total_payload_bytes) / (1024.0 * 1024.0), r->largest_payload_bytes);
    if (o.features == RtabmapFeatureSource::kOrb) {
      std::printf("  ORB features on %llu nodes (%llu without colour and depth), %.2f ms per node\n",
                  static_cast<unsigned long long>(r->orb_keyframes),
                  static_cast<unsigned long long>(r->orb_nodes_without_images),
                  r->orb_keyframes > 0 ? r->extract_ms / static_cast<double>(r->orb_keyframes) : 0.0);
      if (r->vocabulary_trained) {
        std::printf("  vocabulary %u words, %u nodes from %llu descriptors\n", r->vocabulary.words,
                    r->vocabulary.nodes,
                    static_cast<unsigned long long>(r->vocabulary.training_descriptors));
      } else {
        std::printf("  vocabulary: none (no feature to train on)\n");
      }
    }
    if (r->has_camera) {
      std::printf("  camera %ux%u fx=%.2f fy=%.2f cx=%.2f cy=%.2f\n", r->camera.width, r->camera.height,
                  r->camera.fx, r->camera.fy, r->camera.cx, r->camera.cy);
    }
    // What basic starts from with init_wm_with_all_nodes = false (RTAB-Map's default).
    if (r->last_wm_recorded) {
      std::printf("  last working memory %llu nodes (Node.time_enter >= the last Info.time_enter '%s')\n",
                  static_cast<unsigned long long>(r->last_wm_nodes), r->last_info_time_enter.c_str());
    } else {
      std::printf("  last working memory: every node (no Info.time_enter to go by)\n");
    }
  });
}

}  // namespace zm::app
