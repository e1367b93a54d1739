// `zonemap zones annotate DB ZONES`: assigns every keyframe of a map database to its zones
// (containment, doorway band, nearest-zone fallback; or the lists of a keyframe-list file),
// optionally splits zones over a budget, writes zones and memberships in one transaction, and
// prints a per-zone table with a warning for each zone larger than the budget.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "param_options.h"
#include "zones/adjacency.h"
#include "zones/annotate.h"
#include "zones/zone_set.h"

namespace zm::app {
namespace {

struct AnnotateCliOpts {
  std::string db;
  std::string zones;
  double band_m = kDoorwayBandParam.default_value;
  std::uint32_t max_zone_keyframes = 0;
  std::uint32_t warn_keyframes = 0;
  bool json = false;
};

void PrintTable(const AnnotationReport& r, const AnnotateCliOpts& o) {
  std::printf("%-24s %-10s %5s %9s %10s\n", "zone", "kind", "floor", "keyframes", "area_m2");
  for (const Zone& z : r.zones.zones()) {
    const std::uint32_t n = r.counts[static_cast<std::size_t>(z.id.value)];
    const bool over = o.warn_keyframes > 0 && n > o.warn_keyframes;
    std::printf("%-24s %-10s %5d %9u %10.1f%s\n", z.name.c_str(), z.kind.c_str(), z.floor, n,
                z.AreaM2(), over ? "  > budget" : "");
  }
  std::printf("keyframes %llu: inside a zone %llu, doorway-band memberships %llu, "
              "nearest-zone fallback %llu, unassigned %llu\n",
              static_cast<unsigned long long>(r.keyframes),
              static_cast<unsigned long long>(r.inside),
              static_cast<unsigned long long>(r.band_memberships),
              static_cast<unsigned long long>(r.nearest),
              static_cast<unsigned long long>(r.unassigned));
  for (const SplitEntry& e : r.split.entries) {
    std::printf("split %s (%u keyframes > %u) into %zu parts:", e.original.c_str(), e.keyframes,
                r.split.max_keyframes, e.parts.size());
    for (std::size_t i = 0; i < e.parts.size(); ++i) {
      std::printf(" %s=%u", e.parts[i].c_str(), e.part_keyframes[i]);
    }
    std::printf("%s\n", e.polygon_shared ? " (polygon shared: could not clip cleanly)" : "");
  }
}

nlohmann::json ToJson(const AnnotationReport& r, const ZoneGraph& graph) {
  nlohmann::json zones = nlohmann::json::array();
  for (const Zone& z : r.zones.zones()) {
    nlohmann::json nb = nlohmann::json::array();
    for (ZoneId n : graph.Neighbours(z.id)) nb.push_back(r.zones.zone(n).name);
    zones.push_back({{"id", z.id.value},
                     {"name", z.name},
                     {"kind", z.kind},
                     {"floor", z.floor},
                     {"keyframes", r.counts[static_cast<std::size_t>(z.id.value)]},
                     {"area_m2", z.AreaM2()},
                     {"neighbours", nb}});
  }
  nlohmann::json over = nlohmann::json::array();
  for (ZoneId z : r.over_budget) over.push_back(r.zones.zone(z).name);
  nlohmann::json splits = nlohmann::json::array();
  for (const SplitEntry& e : r.split.entries) {
    splits.push_back({{"zone", e.original},
                      {"keyframes", e.keyframes},
                      {"parts", e.parts},
                      {"part_keyframes", e.part_keyframes},
                      {"polygon_shared", e.polygon_shared}});
  }
  return {{"keyframes", r.keyframes},       {"inside", r.inside},
          {"band_memberships", r.band_memberships}, {"nearest", r.nearest},
          {"unassigned", r.unassigned},     {"memberships", r.members.size()},
          {"zones", zones},                 {"over_budget", over},
          {"splits", splits}};
}

void RunAnnotate(const AnnotateCliOpts& o, CommandContext& ctx) {
  constexpr const char* kCmd = "zones annotate";
  auto zones = LoadZoneFile(o.zones);
  if (!zones.ok()) return ctx.Fail(kCmd, zones.status());
  const AnnotateOptions options{.band_m = o.band_m,
                                .warn_zone_keyframes = o.warn_keyframes,
                                .max_zone_keyframes = o.max_zone_keyframes};
  auto report = AnnotateDatabase(o.db, *zones, options);
  if (!report.ok()) return ctx.Fail(kCmd, report.status());
  if (o.json) {
    auto db = MapDb::Open(o.db);
    if (!db.ok()) return ctx.Fail(kCmd, db.status());
    auto links = (*db)->Links();
    if (!links.ok()) return ctx.Fail(kCmd, links.status());
    const ZoneGraph graph = BuildAdjacency(report->zones, report->members, *links);
    std::printf("%s\n", ToJson(*report, graph).dump(2).c_str());
  } else {
    PrintTable(*report, o);
    std::printf("wrote %zu zones and %zu memberships to %s\n", report->zones.size(),
                report->members.size(), o.db.c_str());
  }
  for (ZoneId z : report->over_budget) {
    std::fprintf(stderr,
                 "zonemap zones annotate: warning: zone \"%s\" holds %u keyframes, more than the "
                 "budget of %u; it cannot be loaded whole (use --max-zone-keyframes)\n",
                 report->zones.zone(z).name.c_str(),
                 report->counts[static_cast<std::size_t>(z.value)], o.warn_keyframes);
  }
}

}  // namespace

void AddZonesAnnotateCommand(CLI::App& app, CommandContext& ctx) {
  auto opts = std::make_shared<AnnotateCliOpts>();
  CLI::App* cmd = AddZonesSubcommand(
      app, "annotate",
      "Assign every keyframe of DB to the zones of ZONES and store the memberships");
  cmd->add_option("DB", opts->db, "map database (modified in place: zones replaced)")->required();
  cmd->add_option("ZONES", opts->zones,
                  "zone file: GeoJSON FeatureCollection or {\"zones\": {name: [keyframe ids]}}")
      ->required();
  AddParamOption(*cmd, kDoorwayBandParam, &opts->band_m);
  cmd->add_option("--max-zone-keyframes", opts->max_zone_keyframes,
                  "split zones holding more keyframes than this into compact parts (0 = never)");
  cmd->add_option("--warn-keyframes", opts->warn_keyframes,
                  "warn about zones holding more keyframes than this budget (0 = no warning)");
  cmd->add_flag("--json", opts->json, "print the report (with zone neighbours) as JSON");
  cmd->callback([opts, &ctx] { RunAnnotate(*opts, ctx); });
}

}  // namespace zm::app
