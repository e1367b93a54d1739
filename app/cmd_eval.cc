// `zonemap eval REF EST [--align none|se3|sim3] [--format tum|kitti] [--json]`: APE (translation)
// and RPE (translation and rotation, delta in frames) of an estimate against a reference, with
// evo's conventions (lib/geometry/metrics.h). REF is the ground truth.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "geometry/metrics.h"
#include "geometry/trajectory.h"

namespace zm::app {
namespace {

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count}, {"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
          {"std", s.std},     {"min", s.min},   {"max", s.max},   {"sse", s.sse}};
}

void PrintStats(const char* title, const char* unit, const ErrorStats& s) {
  std::printf("%s (%zu pairs, %s)\n", title, s.count, unit);
  std::printf(
      "  rmse   %.6f\n  mean   %.6f\n  median %.6f\n  std    %.6f\n"
      "  min    %.6f\n  max    %.6f\n  sse    %.6f\n",
      s.rmse, s.mean, s.median, s.std, s.min, s.max, s.sse);
}

}  // namespace

void AddEvalCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string ref, est, align = "none", format = "tum";
    double max_dt_s = kDefaultMaxDtS;
    std::size_t delta = 1;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd =
      app.add_subcommand("eval", "APE and RPE of an estimated trajectory (evo conventions)");
  cmd->add_option("REF", o->ref, "reference (ground truth) trajectory")->required();
  cmd->add_option("EST", o->est, "estimated trajectory")->required();
  cmd->add_option("--align", o->align, "none | se3 | sim3 (Umeyama)")->capture_default_str();
  cmd->add_option("--format", o->format, "tum | kitti (both files)")->capture_default_str();
  cmd->add_option("--max-dt", o->max_dt_s, "association tolerance in seconds")
      ->capture_default_str();
  cmd->add_option("--delta", o->delta, "RPE delta in frames")->capture_default_str();
  cmd->add_flag("--json", o->json, "print JSON");
  cmd->callback([o, &ctx] {
    auto format = ParseTrajectoryFormat(o->format);
    if (!format.ok()) return ctx.Fail("eval", format.status());
    auto align = ParseAlignMode(o->align);
    if (!align.ok()) return ctx.Fail("eval", align.status());
    if (o->delta == 0) return ctx.Fail("eval", "--delta must be at least 1 frame");
    auto ref = ReadTrajectory(o->ref, *format);
    if (!ref.ok()) return ctx.Fail("eval", ref.status());
    auto est = ReadTrajectory(o->est, *format);
    if (!est.ok()) return ctx.Fail("eval", est.status());
    auto r = Evaluate(*ref, *est,
                      {.align = *align, .max_dt_s = o->max_dt_s, .rpe_delta_frames = o->delta});
    if (!r.ok()) return ctx.Fail("eval", r.status());
    if (o->json) {
      const Alignment& a = r->alignment;
      nlohmann::json j = {
          {"ref", o->ref},
          {"est", o->est},
          {"ref_poses", r->ref_poses},
          {"est_poses", r->est_poses},
          {"associated", r->associated},
          {"align", AlignModeName(r->align)},
          {"alignment",
           {{"scale", a.scale},
            {"translation", {a.translation.x(), a.translation.y(), a.translation.z()}},
            {"rotation",
             {a.rotation(0, 0), a.rotation(0, 1), a.rotation(0, 2), a.rotation(1, 0),
              a.rotation(1, 1), a.rotation(1, 2), a.rotation(2, 0), a.rotation(2, 1),
              a.rotation(2, 2)}}}},
          {"ape_trans_m", StatsJson(r->ape_trans_m)},
          {"rpe_delta_frames", o->delta},
          {"rpe_trans_m", StatsJson(r->rpe_trans_m)},
          {"rpe_rot_deg", StatsJson(r->rpe_rot_deg)}};
      std::printf("%s\n", j.dump(2).c_str());
      return;
    }
    std::printf("associated %zu of %zu poses (ref %zu, est %zu), alignment %s", r->associated,
                std::min(r->ref_poses, r->est_poses), r->ref_poses, r->est_poses,
                AlignModeName(r->align));
    if (r->align == AlignMode::kSim3) std::printf(", scale %.6f", r->alignment.scale);
    std::printf("\n");
    PrintStats("APE translation", "m", r->ape_trans_m);
    PrintStats("RPE translation", "m", r->rpe_trans_m);
    PrintStats("RPE rotation", "deg", r->rpe_rot_deg);
  });
}

}  // namespace zm::app
