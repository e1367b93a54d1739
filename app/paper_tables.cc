// The paper-form Table I and Table II (paper_tables.h).
#include "paper_tables.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "harness/repeats.h"

namespace zm::app {
namespace {

using nlohmann::json;

// ../shared/docs/evaluation.md, Table I (Jetson Orin Nano 8 GB, RTAB-Map, qwen3-vl 2B): per
// metric, the row's name, the summary.json pointer of ours, its decimals and the paper's four
// columns (Basic only, Basic + VLM, Semantic only, Semantic + VLM). TimeTotal is the mean tick
// time after the start-up tick; loop closures are the accepted ones, as RTAB-Map counts them.
struct PaperMetric {
  const char* name;
  const char* pointer;
  int decimals;
  int paper_decimals;
  std::array<double, 4> paper;
};
constexpr std::array<PaperMetric, 6> kTable1 = {{
    {"update rate (Hz) ↑", "/update_rate_hz", 2, 2, {0.96, 0.65, 0.96, 0.95}},
    {"loop closures ↑", "/closures_accepted", 0, 0, {53, 31, 35, 33}},
    {"avg TimeTotal (ms) ↓", "/time_total_ms/steady", 1, 2, {779.41, 5064.87, 566.06, 784.81}},
    {"ATE RMSE (m) ↓", "/ate_rmse_m", 3, 3, {0.14, 0.31, 0.18, 0.19}},
    {"RPE translation RMSE (m) ↓", "/rpe_trans_rmse_m", 3, 3, {0.20, 0.42, 0.24, 0.22}},
    {"RPE rotation RMSE (deg) ↓", "/rpe_rot_rmse_deg", 2, 2, {0.38, 1.00, 0.57, 0.32}},
}};

// Table II: per model, the paper's (outcome, median TPS, latency ms) with Basic and with
// Semantic; nullopt where the model did not start.
struct PaperModelRow {
  const char* symbol;
  std::optional<double> tps;
  std::optional<double> latency_ms;
};
struct PaperModel {
  const char* model;
  PaperModelRow basic, semantic;
};
const std::array<PaperModel, 5> kTable2 = {{
    {"qwen3-vl-2b", {"△", 32.43, 9642}, {"○", 33.36, 10260}},
    {"qwen3-vl-4b", {"×", std::nullopt, std::nullopt}, {"×", std::nullopt, std::nullopt}},
    {"qwen3.5-0.8b", {"△", 29.80, 30396}, {"○", 31.22, 23812}},
    {"qwen3.5-2b", {"×", std::nullopt, std::nullopt}, {"×", std::nullopt, std::nullopt}},
    {"gemma3-4b", {"○", 14.38, 13175}, {"○", 15.19, 11880}},
}};

// The paper's configurations in its column order.
constexpr std::array<std::pair<const char*, bool>, 4> kConfigs = {
    {{"basic", false}, {"basic", true}, {"semantic", false}, {"semantic", true}}};

// Summaries older than the current schema keep the same figure under another pointer: TimeTotal
// before issue 27 was tick_ms.mean; schema version 1 had one count, loop_closures, for the
// closures accepted and the frames localized.
const char* LegacyPointer(const std::string& pointer) {
  if (pointer == "/time_total_ms/steady") return "/tick_ms/mean";
  if (pointer == "/closures_accepted" || pointer == "/frames_localized") return "/loop_closures";
  return nullptr;
}

const char* Symbol(const std::string& outcome) {
  if (outcome == "completed") return "○";
  if (outcome == "stalled") return "△";
  if (outcome == "failed_to_start" || outcome == "failed") return "×";
  if (outcome == "killed") return "†";
  return "";
}

std::string Capitalized(std::string s) {
  if (!s.empty() && s[0] >= 'a' && s[0] <= 'z') s[0] = static_cast<char>(s[0] - 'a' + 'A');
  return s;
}

std::string ConfigName(const std::string& policy, bool with_vlm) {
  return Capitalized(policy) + (with_vlm ? " + VLM" : " only");
}

// A number field of a JSON object; 0 where it is missing, null or not a number.
double Num(const json& obj, const char* key) {
  if (!obj.is_object()) return 0.0;
  const auto it = obj.find(key);
  return it != obj.end() && it->is_number() ? it->get<double>() : 0.0;
}

// "%g", as the reports state scales and compressions.
std::string G(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

std::string Join(const std::vector<std::string>& parts, const char* sep) {
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i != 0) out += sep;
    out += parts[i];
  }
  return out;
}

// One cell of results.json, shown as one configuration: its statistics, and its representative
// repeat's summary for what is stated once (the device, the clock).
class Cell {
 public:
  explicit Cell(const json& cell) : j_(&cell) {}

  [[nodiscard]] const std::string& name() const {
    return (*j_)["cell"].get_ref<const std::string&>();
  }
  [[nodiscard]] std::string policy() const { return j_->value("policy", std::string("?")); }
  [[nodiscard]] std::string label() const { return j_->value("policy_label", policy()); }
  [[nodiscard]] std::string model() const { return j_->value("model", std::string("none")); }
  [[nodiscard]] bool with_vlm() const { return model() != "none"; }
  [[nodiscard]] std::uint64_t k_max() const {
    return static_cast<std::uint64_t>(Num(*j_, "k_max"));
  }
  // The runs of the cell (every repeat's summary.json).
  [[nodiscard]] const json& runs() const {
    static const json kNone = json::array();
    const auto it = j_->find("runs");
    return it != j_->end() && it->is_array() ? *it : kNone;
  }
  [[nodiscard]] std::uint32_t n() const { return static_cast<std::uint32_t>(runs().size()); }

  // The representative repeat's summary (results.json's representative_repeat).
  [[nodiscard]] const json& summary() const {
    static const json kEmpty = json::object();
    const json& r = runs();
    if (r.empty()) return kEmpty;
    const auto i = static_cast<std::size_t>(Num(*j_, "representative_repeat"));
    return i < r.size() ? r[i] : r[0];
  }

  // The cell's statistic at a summary.json pointer; null when no run had it.
  [[nodiscard]] const json& Stat(const std::string& pointer) const {
    static const json kNone;
    const auto st = j_->find("stats");
    if (st == j_->end() || !st->is_object()) return kNone;
    const auto it = st->find(pointer);
    return it == st->end() ? kNone : *it;
  }
  [[nodiscard]] bool Has(const std::string& pointer) const { return !Stat(pointer).is_null(); }
  [[nodiscard]] const json& StatOrLegacy(const std::string& pointer) const {
    const json& st = Stat(pointer);
    const char* legacy = LegacyPointer(pointer);
    return st.is_null() && legacy != nullptr ? Stat(legacy) : st;
  }

  // Mean ± 95 % CI in the paper's form: thousands grouped, the column's n in its header.
  [[nodiscard]] std::string Format(const json& stat, int decimals, double scale = 1.0) const {
    return FormatStat(stat, decimals, scale, n(),
                      StatStyle{.group_thousands = true, .n_in_header = true});
  }
  [[nodiscard]] std::string FormatAt(const std::string& pointer, int decimals,
                                     double scale = 1.0) const {
    return Format(Stat(pointer), decimals, scale);
  }

  // A string field over the repeats: (value, count) in first-seen order; a run without it counts
  // under nullopt.
  [[nodiscard]] std::vector<std::pair<std::optional<std::string>, int>> Tally(
      const std::string& pointer) const {
    std::vector<std::pair<std::optional<std::string>, int>> out;
    const json::json_pointer ptr(pointer);
    for (const json& run : runs()) {
      std::optional<std::string> v;
      if (run.contains(ptr) && run[ptr].is_string()) v = run[ptr].get<std::string>();
      auto it = std::find_if(out.begin(), out.end(), [&](const auto& p) { return p.first == v; });
      if (it == out.end()) {
        out.emplace_back(v, 1);
      } else {
        ++it->second;
      }
    }
    return out;
  }

  // An outcome over the repeats: "○ completed" when all agree, else "○ completed 2, † killed 1".
  [[nodiscard]] std::string TallyText(const std::string& pointer) const {
    const auto tally = Tally(pointer);
    std::vector<std::string> parts;
    for (const auto& [v, count] : tally) {
      if (!v) continue;
      const std::string sym = Symbol(*v);
      std::string text = sym.empty() ? *v : sym + " " + *v;
      parts.push_back(tally.size() == 1 ? text : text + " " + std::to_string(count));
    }
    return parts.empty() ? "–" : Join(parts, ", ");
  }

  // The experiment's time compression (pace_speedup before it had the name); 0 = unpaced.
  [[nodiscard]] double time_compression() const {
    const json& s = summary();
    for (const char* key : {"time_compression", "pace_speedup"}) {
      if (Num(s, key) != 0.0) return Num(s, key);
    }
    return 0.0;
  }

 private:
  const json* j_;
};

// The configuration's cell: policy, with or without the co-tenant, optionally one model; where
// several budgets ran, the one with the smallest K_max (the first of equals, by cell name).
const Cell* Pick(const std::vector<Cell>& cells, const std::string& policy, bool with_vlm,
                 const std::string* model) {
  const Cell* best = nullptr;
  for (const Cell& c : cells) {
    if (c.policy() != policy || c.with_vlm() != with_vlm) continue;
    if (model != nullptr && with_vlm && c.model() != *model) continue;
    if (c.label().find("unsliced") != std::string::npos) continue;
    if (best == nullptr || c.k_max() < best->k_max()) best = &c;
  }
  return best;
}

// How the device was modelled, for every report: kind, limit, scale, time compression.
std::string DeviceText(const Cell& c) {
  const json& s = c.summary();
  static const json kNoDevice = json::object();
  const json& dev = s.contains("device") && s["device"].is_object() ? s["device"] : kNoDevice;
  const std::string kind = dev.contains("kind") && dev["kind"].is_string()
                               ? dev["kind"].get<std::string>()
                               : std::string();
  std::vector<std::string> parts;
  if (kind == "cgroup") {
    parts.emplace_back("device: memory cgroup (the kernel's OOM killer)");
  } else if (kind == "ledger") {
    parts.emplace_back("device: ledger (SIMULATED: no memory cgroup)");
  } else {
    parts.emplace_back("device: ledger (SIMULATED; written before the cgroup device existed)");
  }
  const double limit = Num(dev, "limit_bytes");
  if (limit != 0.0)
    parts.push_back("limit " + FormatNumber(limit / 1073741824.0, 2, false) + " GiB");
  double scale = Num(s, "device_scale");
  if (scale == 0.0) scale = Num(dev, "scale");
  if (scale == 0.0 && s.contains("cotenant")) scale = Num(s["cotenant"], "device_scale");
  parts.push_back(scale != 0.0 ? "device scale " + G(scale) : std::string("device scale 1"));
  const double tc = c.time_compression();
  parts.push_back(tc != 0.0 ? "time compression " + G(tc) + "x"
                            : std::string("no time compression (unpaced)"));
  return Join(parts, ", ");
}

using Columns = std::array<const Cell*, 4>;

// What the paper's Table I leaves implicit and ours must state: TimeTotal the other ways
// (lib/runtime/summary.h, TimeTotalJson), frames, the device, outcomes.
std::vector<std::pair<std::string, std::string (*)(const Cell&)>> ExtraRows() {
  return {
      {"avg TimeTotal incl. the start-up tick (ms)",
       [](const Cell& c) { return c.FormatAt("/time_total_ms/with_startup", 1); }},
      {"avg TimeTotal without the idle-time loads (ms)",
       [](const Cell& c) { return c.FormatAt("/time_total_ms/without_idle_loads", 1); }},
      {"avg TimeTotal with the idle-time loads (ms)",
       [](const Cell& c) { return c.FormatAt("/time_total_ms/with_idle_loads", 1); }},
      {"frames localized (a closure accepted on the frame)",
       [](const Cell& c) { return c.Format(c.StatOrLegacy("/frames_localized"), 0); }},
      {"frames dropped of arrived",
       [](const Cell& c) {
         return c.FormatAt("/frames_dropped", 0) + " of " + c.FormatAt("/frames_arrived", 0);
       }},
      {"device OOM kills", [](const Cell& c) { return c.FormatAt("/device/oom_kills", 1); }},
      {"device peak",
       [](const Cell& c) {
         const char* p =
             c.Has("/device/peak_bytes") ? "/device/peak_bytes" : "/device/peak_sum_bytes";
         return c.Has(p) ? c.FormatAt(p, 2, 1e-9) + " GB" : std::string("–");
       }},
      {"device swap peak (MB)",
       [](const Cell& c) { return c.FormatAt("/device/swap/peak_bytes", 1, 1e-6); }},
      {"device DRAM peak: usage + zram's store (GB)",
       [](const Cell& c) {
         return c.Has("/device/dram_peak_bytes") ? c.FormatAt("/device/dram_peak_bytes", 2, 1e-9)
                                                 : std::string("–");
       }},
      {"limit writes refused: over the device's DRAM",
       [](const Cell& c) {
         return c.Has("/device/limit_charge_refusals")
                    ? c.FormatAt("/device/limit_charge_refusals", 0)
                    : std::string("–");
       }},
      {"map major faults", [](const Cell& c) { return c.FormatAt("/map/major_faults", 0); }},
      {"map process outcome", [](const Cell& c) { return c.TallyText("/map/outcome"); }},
      {"co-tenant outcome",
       [](const Cell& c) {
         if (!c.with_vlm()) return std::string("–");
         std::string text = c.TallyText("/cotenant/outcome");
         const json& restarts = c.Stat("/cotenant/restarts");
         if (Num(restarts, "max") != 0.0) text += ", restarts " + c.Format(restarts, 1);
         return text;
       }},
  };
}

std::string Table1(const Columns& cols) {
  std::string head = "| metric |";
  for (std::size_t j = 0; j < kConfigs.size(); ++j) {
    const Cell* c = cols[j];
    head += ' ' + ConfigName(kConfigs[j].first, kConfigs[j].second);
    if (c != nullptr) head += c->n() == 1 ? " (1 run)" : " (n = " + std::to_string(c->n()) + ")";
    head += " |";
  }
  std::string out = head + "\n|---|---|---|---|---|\n";
  for (const PaperMetric& m : kTable1) {
    out += std::string("| ") + m.name + " |";
    for (std::size_t j = 0; j < cols.size(); ++j) {
      const Cell* c = cols[j];
      const std::string ours =
          c != nullptr ? c->Format(c->StatOrLegacy(m.pointer), m.decimals) : "–";
      out += ' ' + ours + " (" + FormatNumber(m.paper[j], m.paper_decimals, true) + ") |";
    }
    out += '\n';
  }
  for (const auto& [name, cell] : ExtraRows()) {
    out += "| " + name + " |";
    for (const Cell* c : cols) out += ' ' + (c != nullptr ? cell(*c) : std::string("–")) + " |";
    out += '\n';
  }
  out.pop_back();
  return out;
}

// Table II's columns of ours: (header, pointer, decimals).
struct Table2Column {
  const char* header;
  const char* pointer;
  int decimals;
};
constexpr std::array<Table2Column, 7> kTable2Columns = {{
    {"requests completed", "/cotenant/requests_completed", 1},
    {"TPS median", "/cotenant/tokens_per_s", 2},
    {"TPS aggregate", "/cotenant/tokens_per_s_aggregate", 2},
    {"latency p50 (ms)", "/cotenant/latency_ms/p50", 0},
    {"latency mean (ms)", "/cotenant/latency_ms/mean", 0},
    {"latency p95 (ms)", "/cotenant/latency_ms/p95", 0},
    {"major faults", "/cotenant/major_faults", 0},
}};

std::string Optional(const std::optional<double>& v, int decimals) {
  return v ? FormatNumber(*v, decimals, true) : std::string("–");
}

std::string Table2(const std::vector<Cell>& cells) {
  std::vector<std::string> models;
  for (const Cell& c : cells) {
    if (c.with_vlm() && std::find(models.begin(), models.end(), c.model()) == models.end())
      models.push_back(c.model());
  }
  if (models.empty()) return "";
  std::string out = "| model (stand-in) | policy | runs | outcome |";
  for (const Table2Column& col : kTable2Columns) out += std::string(" ") + col.header + " |";
  out += "\n|---|---|---|---|";
  for (std::size_t i = 0; i < kTable2Columns.size(); ++i) out += "---|";
  out += '\n';
  for (const std::string& m : models) {
    for (const char* policy : {"basic", "semantic"}) {
      const Cell* c = Pick(cells, policy, true, &m);
      if (c == nullptr) continue;
      std::vector<std::string> row;
      for (const Table2Column& col : kTable2Columns)
        row.push_back(c->FormatAt(col.pointer, col.decimals));
      const json& planned = c->Stat("/cotenant/requests_planned");
      if (Num(planned, "n") > 0) {
        const auto whole = static_cast<std::int64_t>(Num(planned, "mean"));  // whole requests
        row[0] += " of " + FormatNumber(static_cast<double>(whole), 0, true);
      }
      out += "| " + m + " | " + Capitalized(policy) + " | " + std::to_string(c->n()) + " | " +
             c->TallyText("/cotenant/outcome") + " | " + Join(row, " | ") + " |\n";
    }
    const auto paper = std::find_if(kTable2.begin(), kTable2.end(),
                                    [&](const PaperModel& p) { return m == p.model; });
    if (paper == kTable2.end()) continue;
    for (const auto& [name, p] :
         {std::pair{"Basic", paper->basic}, std::pair{"Semantic", paper->semantic}}) {
      out += "| " + m + ": the paper | " + name + " | 1 | " + p.symbol + " | | " +
             Optional(p.tps, 2) + " | – | " + Optional(p.latency_ms, 0) + " | – | – | – |\n";
    }
  }
  out.pop_back();
  return out;
}

// How the co-tenant's weights were held (summary.json cotenant.weights, issue 27 §1).
std::string WeightsText(const Columns& cols) {
  std::set<std::string> kinds;
  for (const Cell* c : cols) {
    if (c == nullptr || !c->with_vlm()) continue;
    for (const auto& [v, count] : c->Tally("/cotenant/weights")) {
      if (v && !v->empty()) kinds.insert(*v);
    }
  }
  if (kinds.empty()) return "";
  return " (weights " + Join(std::vector<std::string>(kinds.begin(), kinds.end()), ", ") + ")";
}

std::string RepeatsText(const Columns& cols) {
  std::set<std::uint32_t> ns;
  for (const Cell* c : cols) {
    if (c != nullptr) ns.insert(c->n());
  }
  if (ns == std::set<std::uint32_t>{1}) return "One run per configuration.";
  std::vector<std::string> parts;
  for (std::uint32_t n : ns) parts.push_back(std::to_string(n));
  return Join(parts, " or ") +
         " runs per configuration, interleaved (ABAB...); the figures show each configuration's "
         "representative run (mean tick time nearest the median).";
}

// A table under its heading with its note below, or nothing where the table is empty.
void Section(std::vector<std::string>* parts, const std::string& heading, const std::string& table,
             const std::string& note) {
  if (table.empty()) return;
  parts->push_back("### " + heading + "\n");
  parts->push_back(table + "\n");
  parts->push_back(note);
}

constexpr const char* kTable1Note =
    "Each cell: ours, mean ± 95 % CI over the column's runs (Student's t, n − 1 dof; one run: "
    "its value), then (the paper's, one run). avg TimeTotal = the mean tick time after the "
    "start-up tick (RTAB-Map's TimeTotal is its per-frame processing time); incl. the start-up "
    "tick: the start-up load counted in; without the idle-time loads: the ticks' own steps, the "
    "waits on idle-time loads taken out; with the idle-time loads: every idle-time load's wall "
    "time charged to the ticks, as if loaded inside them (RTAB-Map's loads are).\n";
constexpr const char* kTable2Note =
    "○ completed, △ stalled (watchdog), × failed to start, † killed (OOM; restarted by the "
    "supervisor). TPS median = the median request's decode tokens/s; TPS aggregate = all answer "
    "tokens ÷ all decode time (slow requests weigh by their length); latency = a request's start "
    "to its last token (prompt processing + decode); p50/p95 nearest rank over the run's "
    "completed requests. Each cell: mean ± 95 % CI over the runs (Student's t), a per-run figure "
    "averaged. The paper's Table II gives one run's median TPS and latency.\n";

}  // namespace

std::string PaperTablesMarkdown(const json& results) {
  // Per scenario (in name order), its cells in cell-name order: the order the first of equal
  // candidates is picked in.
  std::map<std::string, std::vector<Cell>> scenarios;
  for (const json& cell : results) {
    if (!cell.is_object() || !cell.contains("cell") || !cell["cell"].is_string()) continue;
    scenarios[cell.value("scenario_name", std::string("run"))].emplace_back(cell);
  }
  std::vector<std::string> parts;
  for (auto& [scenario, cells] : scenarios) {
    std::stable_sort(cells.begin(), cells.end(),
                     [](const Cell& a, const Cell& b) { return a.name() < b.name(); });
    Columns cols{};
    for (std::size_t j = 0; j < kConfigs.size(); ++j)
      cols[j] = Pick(cells, kConfigs[j].first, kConfigs[j].second, nullptr);
    const bool any =
        std::any_of(cols.begin(), cols.end(), [](const Cell* c) { return c != nullptr; });
    const Cell* first = &cells.front();
    for (const Cell* c : cols) {
      if (c != nullptr) {
        first = c;
        break;
      }
    }
    std::set<std::uint64_t> ks;
    std::set<double> tcs;
    for (const Cell* c : cols) {
      if (c == nullptr) continue;
      if (c->k_max() != 0) ks.insert(c->k_max());
      tcs.insert(c->time_compression());
    }
    std::string differ;
    if (tcs.size() > 1) {
      std::vector<std::string> t;
      for (double tc : tcs) t.push_back(tc != 0.0 ? G(tc) + "x" : std::string("unpaced"));
      differ = " (first run; NOT the same in every run: " + Join(t, ", ") + ")";
    }
    std::string k;
    if (!ks.empty()) {
      std::vector<std::string> t;
      for (std::uint64_t v : ks) t.push_back(std::to_string(v));
      k = "; MemoryThr (K_max) " + Join(t, ", ");
    }
    parts.push_back("## " + scenario + ": the paper's tables\n");
    parts.push_back(DeviceText(*first) + differ + k +
                    ". The co-tenant is a stand-in for VLM decoding" + WeightsText(cols) + ". " +
                    RepeatsText(cols) + " Each cell: ours (the paper's, Jetson Orin Nano 8 GB).\n");
    Section(&parts, "Table I analogue: SLAM with and without the co-tenant",
            any ? Table1(cols) : std::string(), kTable1Note);
    Section(&parts, "Table II analogue: the co-tenant beside SLAM", Table2(cells), kTable2Note);
  }
  return Join(parts, "\n");
}

}  // namespace zm::app
