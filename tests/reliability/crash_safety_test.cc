// Crash safety of the commands that write a map database (issue 11): `zonemap import-rtabmap`,
// `zonemap zones annotate` and `zonemap sim hospital` are killed with SIGKILL at random points
// (seeded, bounded: kKills per command) and the result is reopened each time with MapDb::Open.
// The database must be the old state or the new one (or absent when there was no old file),
// never a mix: Open succeeds and a digest of everything in it (keyframes, links, zones,
// memberships, every payload loaded and CRC-checked) equals the digest of one of the two states.
//
// The zonemap binary is ZM_BINARY_DIR/app/zonemap. In a cross build (ZM_EMULATOR non-empty,
// from CMAKE_CROSSCOMPILING_EMULATOR) these cases are skipped with a message; Run() would put
// the emulator in front of the binary.
#include <doctest/doctest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "import/rtabmap_test_util.h"

namespace zm {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

constexpr int kKills = 10;

// In a cross build the zonemap binary would run under qemu: each kill series would take
// minutes, and what is tested (SQLite transactions, rename) does not depend on the CPU. Skipped
// there, said so.
bool Skip() {
  if (std::string(ZM_EMULATOR).empty()) return false;
  MESSAGE("skipped in a cross build (zonemap would run under " << ZM_EMULATOR << ")");
  return true;
}

const std::string kZonemap = std::string(ZM_BINARY_DIR) + "/app/zonemap";

// Runs zonemap with `args` (stdout/stderr to /dev/null). kill_after_s < 0: run to the end.
// Returns the exit status (or -SIGKILL when it was killed) and the wall time.
struct RunResult {
  int status = 0;
  double seconds = 0.0;
  bool killed = false;
};
RunResult Run(const std::vector<std::string>& args, double kill_after_s = -1.0) {
  std::vector<std::string> argv;
  // ZM_EMULATOR: the emulator's words joined by '|' (empty natively).
  std::istringstream emulator(ZM_EMULATOR);
  for (std::string word; std::getline(emulator, word, '|');) {
    if (!word.empty()) argv.push_back(word);
  }
  argv.push_back(kZonemap);
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> cargv;
  for (auto& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    const int null = open("/dev/null", O_WRONLY);
    dup2(null, 1);
    dup2(null, 2);
    execv(cargv[0], cargv.data());
    _exit(127);
  }
  RunResult r;
  int wstatus = 0;
  if (kill_after_s >= 0.0) {
    const auto deadline = t0 + std::chrono::duration<double>(kill_after_s);
    // Poll so a run that ends before the deadline is not "killed" afterwards.
    while (std::chrono::steady_clock::now() < deadline) {
      if (waitpid(pid, &wstatus, WNOHANG) == pid) {
        r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -WTERMSIG(wstatus);
        return r;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    kill(pid, SIGKILL);
    r.killed = true;
  }
  REQUIRE(waitpid(pid, &wstatus, 0) == pid);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -WTERMSIG(wstatus);
  return r;
}

// Everything a map database holds, as text; "open failed: ..." when it does not open.
std::string Digest(const std::string& path) {
  auto db = MapDb::Open(path);
  if (!db.ok()) return "open failed: " + db.status().ToString();
  MapDb& map = **db;
  std::ostringstream out;
  auto kfs = map.Keyframes();
  auto links = map.Links();
  auto zones = map.Zones();
  auto members = map.ZoneMembers();
  if (!kfs.ok() || !links.ok() || !zones.ok() || !members.ok()) return "metadata read failed";
  out << "source " << map.metadata().source << "\nkeyframes";
  for (const auto& k : *kfs) out << ' ' << k.id.value << ':' << k.payload_bytes << ':' << k.weight;
  out << "\nlinks " << links->size();
  for (const auto& l : *links) out << ' ' << l.from.value << '-' << l.to.value;
  out << "\nzones";
  for (const auto& z : *zones) out << ' ' << z.name << '/' << z.kind << '/' << z.polygon.size();
  out << "\nmembers";
  for (const auto& m : *members) out << ' ' << m.zone.value << ':' << m.keyframe.value;
  // Every payload, loaded and CRC-checked (MapDb verifies on load), one keyframe at a time.
  Arena arena = test::MakeArena(1, std::max<std::uint64_t>(map.metadata().largest_payload_bytes, 64));
  std::uint32_t crc = 0;
  test::RecordingSink sink(kfs->empty() ? 0 : static_cast<std::size_t>(kfs->back().id.value));
  for (const auto& k : *kfs) {
    sink.Clear();
    const KeyframeId id[] = {k.id};
    auto st = map.LoadKeyframes(id, arena, sink);
    if (!st.ok()) return "payload load failed: " + st.status().ToString();
    for (const auto& e : sink.loaded()) {
      crc ^= Crc32(arena.Slot(e.slot).first(e.bytes)) + static_cast<std::uint32_t>(k.id.value);
      arena.Release(e.slot);
    }
  }
  out << "\npayload crc " << crc << '\n';
  return out.str();
}

void RemoveDb(const std::string& path) {
  for (const char* s : {"", "-wal", "-shm", "-journal", ".tmp", ".tmp-wal", ".tmp-shm", ".tmp-journal"}) {
    std::error_code ec;
    fs::remove(path + s, ec);
  }
}

void CopyDb(const std::string& from, const std::string& to) {
  RemoveDb(to);
  fs::copy_file(from, to);
}

// Kills `args` kKills times at uniformly random points in [0, 1.1 x its full run time]; before
// each run `prepare()` restores the old state. After each kill the database at `db` must digest
// to `old_state` or `new_state` ("" = the file must then be absent).
template <class Prepare>
void KillRepeatedly(const char* what, const std::vector<std::string>& args, const std::string& db,
                    double full_s, const std::string& old_state, const std::string& new_state,
                    Prepare prepare, unsigned seed, int kills = kKills) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> when(0.0, 1.1 * full_s);
  int killed = 0, olds = 0, news = 0, absent = 0;
  for (int i = 0; i < kills; ++i) {
    prepare();
    const double t = when(rng);
    const RunResult r = Run(args, t);
    killed += r.killed ? 1 : 0;
    const std::string command = what;
    CAPTURE(command);
    CAPTURE(t);
    if (!fs::exists(db)) {
      CHECK(old_state.empty());
      ++absent;
      continue;
    }
    const std::string d = Digest(db);
    const bool is_old = !old_state.empty() && d == old_state;
    const bool is_new = d == new_state;
    INFO("after a kill at " << t << " s the database holds:\n" << d.substr(0, 400));
    CHECK((is_old || is_new));
    olds += is_old ? 1 : 0;
    news += is_new ? 1 : 0;
  }
  MESSAGE(std::string(what) << ": full run " << full_s << " s; " << killed << " of " << kills
               << " runs killed; afterwards old " << olds << ", new " << news << ", absent " << absent);
}

// An RTAB-Map database of `nodes` nodes on a line with neighbour links and a loop closure
// every 10th node, calibration and no images (pose-only maps are valid).
void MakeRtabmap(const std::string& path, int nodes) {
  test::RtabDb db(path, test::kRtabmapSchema023);
  for (int i = 1; i <= nodes; ++i) {
    db.AddNode(i, 1, test::PoseBlob(PoseFromXYYaw(0.5 * i, 0.1 * (i % 7), 0.01 * i)));
    if (i > 1) db.AddLink(i - 1, i, 0, test::PoseBlob(PoseFromXYYaw(0.5, 0, 0)));
    if (i > 10 && i % 10 == 0) db.AddLink(i - 10, i, 1, test::PoseBlob(PoseFromXYYaw(5, 0, 0)));
  }
}

TEST_CASE("crash safety: import-rtabmap killed at random points leaves no OUT or a whole one" *
          doctest::test_suite("slow")) {
  if (Skip()) return;
  TempDir dir;
  const std::string in = dir.File("rtabmap.db");
  const std::string in_old = dir.File("rtabmap_old.db");
  const std::string out = dir.File("out.db");
  MakeRtabmap(in, 3000);
  MakeRtabmap(in_old, 40);
  // The new state, and the time a whole run takes.
  const RunResult full = Run({"import-rtabmap", "-q", in, out});
  REQUIRE(full.status == 0);
  const std::string new_state = Digest(out);
  REQUIRE(new_state.rfind("source", 0) == 0);
  RemoveDb(out);

  SUBCASE("new file") {
    KillRepeatedly("import-rtabmap (new OUT)", {"import-rtabmap", "-q", in, out}, out, full.seconds, "",
                   new_state, [&] { RemoveDb(out); }, 1);
  }
  SUBCASE("replacing an existing OUT with --overwrite") {
    const std::string old_db = dir.File("old.db");
    REQUIRE(Run({"import-rtabmap", "-q", in_old, old_db}).status == 0);
    const std::string old_state = Digest(old_db);
    REQUIRE(old_state != new_state);
    KillRepeatedly("import-rtabmap --overwrite", {"import-rtabmap", "-q", "--overwrite", in, out}, out,
                   full.seconds, old_state, new_state, [&] { CopyDb(old_db, out); }, 2);
  }
}

// A grid of rectangular rooms covering x in [0, w], y in [-1, 1] as GeoJSON.
std::string GridZones(int rooms, double w) {
  std::ostringstream s;
  s << R"({"type":"FeatureCollection","features":[)";
  for (int i = 0; i < rooms; ++i) {
    const double x0 = w * i / rooms, x1 = w * (i + 1) / rooms;
    s << (i ? "," : "") << R"({"type":"Feature","properties":{"name":"R)" << i
      << R"(","kind":"room"},"geometry":{"type":"Polygon","coordinates":[[[)" << x0 << ",-1],["
      << x1 << ",-1],[" << x1 << ",1],[" << x0 << ",1],[" << x0 << ",-1]]]}}";
  }
  s << "]}";
  return s.str();
}

TEST_CASE("crash safety: zones annotate killed at random points leaves the old zones or the new ones" *
          doctest::test_suite("slow")) {
  if (Skip()) return;
  TempDir dir;
  const std::string base = dir.File("base.db");
  const std::string db = dir.File("map.db");
  test::MapSpec spec;
  spec.count = 3000;
  spec.features = 2;
  spec.dense_bytes = 16;
  spec.members = {{1, 2, 3}, {4, 5}};  // the old zones: 2 zones, 5 members
  // BuildMap places keyframe i at (i, -i): annotate against rooms along that diagonal's x.
  test::BuildMap(base, spec);
  const std::string zones = dir.File("zones.geojson");
  {
    std::ofstream(zones) << GridZones(60, 3000.0);
  }
  const std::string old_state = Digest(base);
  CopyDb(base, db);
  const RunResult full = Run({"zones", "annotate", db, zones});
  REQUIRE(full.status == 0);
  const std::string new_state = Digest(db);
  REQUIRE(new_state.rfind("source", 0) == 0);
  REQUIRE(new_state != old_state);
  KillRepeatedly("zones annotate", {"zones", "annotate", db, zones}, db, full.seconds, old_state, new_state,
                 [&] { CopyDb(base, db); }, 3);
}

TEST_CASE("crash safety: sim hospital killed at random points leaves no map or the old map or the new one" *
          doctest::test_suite("slow")) {
  if (Skip()) return;
  TempDir dir;
  const std::string out = dir.File("scenario");
  const std::string old_out = dir.File("scenario_old");
  // The smallest hospital, few features, small depth images and a short patrol: the writing
  // of map.db is what is tested, the rest only has to be short (the oracle's features, named).
  const auto sim = [](const std::string& seed, const std::string& folder) {
    return std::vector<std::string>{
        "sim",        "hospital", "--area",  "300",   "--seed",         seed,
        "--tasks",    "2",        "--dense", "64x48", "--max-features", "100",
        "--features", "oracle",  // 64x48: no room for ORB
        "--quiet",    "--out",    folder};
  };
  const RunResult full = Run(sim("1", out));
  REQUIRE(full.status == 0);
  const std::string new_state = Digest(out + "/map.db");
  REQUIRE(new_state.rfind("source", 0) == 0);
  REQUIRE(Run(sim("2", old_out)).status == 0);
  const std::string old_state = Digest(old_out + "/map.db");
  REQUIRE(old_state != new_state);
  // kKills in all: half into a new folder, half over an existing scenario.
  KillRepeatedly("sim hospital (new folder)", sim("1", out), out + "/map.db", full.seconds, "", new_state,
                 [&] { fs::remove_all(out); }, 4, kKills / 2);
  KillRepeatedly("sim hospital (over an old scenario)", sim("1", out), out + "/map.db", full.seconds,
                 old_state, new_state,
                 [&] {
                   fs::remove_all(out);
                   fs::copy(old_out, out, fs::copy_options::recursive);
                 },
                 5, kKills - kKills / 2);
}

}  // namespace
}  // namespace zm
