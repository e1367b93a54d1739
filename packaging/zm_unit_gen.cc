// zm_unit_gen: writes the systemd drop-in that gives zonemapd@<profile>.service its memory limits,
// from the profile's own numbers through the core's budget function (MapShareBytes, the one
// derivation; docs/runtime.md). Run at build time (under qemu when cross-compiling), once per
// shipped profile:
//
//   zm_unit_gen OUT_DIR profiles/orin-nano-8gb.toml [...]
//     -> OUT_DIR/zonemapd@orin-nano-8gb.service.d/50-budget.conf
//
// MemoryMax is the profile's map share: the keyframe slots (K_max x slot bytes) plus
// map.overhead_bytes (SQLite, indexes, code) never exceed it by construction, so a cgroup limit
// at the share turns a leak into this service's out-of-memory kill instead of the VLM's.
// LimitMEMLOCK is the same share, enough for map.lock_arena. A profile with no device memory
// and no explicit share (0) gets no limit ("infinity").
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "runtime/budget.h"
#include "runtime/profile.h"

namespace {

int Fail(const std::string& m) {
  std::fprintf(stderr, "zm_unit_gen: %s\n", m.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return Fail("usage: zm_unit_gen OUT_DIR PROFILE.toml...");
  const std::filesystem::path out = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::filesystem::path file = argv[i];
    auto profile = zm::LoadProfile(file.string());
    if (!profile.ok()) return Fail(profile.status().message());
    auto share = zm::MapShareBytes(profile.value());
    if (!share.ok()) return Fail(share.status().message());
    const std::string name = file.stem().string();
    const std::filesystem::path dir = out / ("zonemapd@" + name + ".service.d");
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) return Fail("cannot create " + dir.string() + ": " + ec.message());
    const std::string limit = *share == 0 ? std::string("infinity") : std::to_string(*share);
    std::ofstream f(dir / "50-budget.conf");
    f << "# Generated at build time by zm_unit_gen from profiles/" << file.filename().string()
      << " (the core's MapShareBytes).\n"
      << "# Map share of \"" << profile->device.name << "\" beside model \"" << profile->model.name
      << "\": " << (*share == 0 ? std::string("unlimited") : zm::FormatBytes(*share)) << ".\n"
      << "# zonemapd's keyframe slots plus map.overhead_bytes stay within it by construction.\n"
      << "[Service]\n"
      << "MemoryMax=" << limit << "\n"
      << "LimitMEMLOCK=" << limit << "\n";
    f.close();
    if (!f) return Fail("cannot write " + (dir / "50-budget.conf").string());
  }
  return 0;
}
