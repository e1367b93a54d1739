// Shared by the co-tenant's tests: a small configuration (a few MiB of weights, so every test runs
// in well under a second even under ASan or qemu), a weights cache private to the tests, and the
// emulator launcher for child processes under qemu-user.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "harness/cotenant.h"

namespace zm::test {

// Reused across runs (the files are created once, like the real cache).
inline std::string TestWeightsDir() {
  return (std::filesystem::temp_directory_path() /
          ("zm-cotenant-test-cache-" + std::to_string(static_cast<unsigned long>(getuid()))))
      .string();
}

// qwen3-vl-2b at device scale 0.002: 3.8 MB of weights, 229 B of KV cache per token.
inline CotenantConfig SmallCotenant() {
  CotenantConfig c;
  c.model = "qwen3-vl-2b";
  c.device_scale = 0.002;
  c.options.prompt_tokens = 64;
  c.options.prompt_batch_tokens = 64;
  c.options.answer_tokens = 4;
  c.options.context_tokens = 256;
  c.options.watchdog_s = 0.0;
  c.options.weights_dir = TestWeightsDir();
  // The file-mapping behaviours these tests check; pinned has its own cases (cotenant_test.cc).
  c.options.weights = CotenantWeights::kMmap;
  c.requests = 2;
  return c;
}

// Runs child processes through the emulator when the tests themselves run under one.
struct EmulatorLauncher {
  EmulatorLauncher() {
    const std::string emulator = ZM_TEST_EMULATOR;
    if (!emulator.empty()) setenv("ZM_COTENANT_LAUNCHER", emulator.c_str(), 1);
  }
  ~EmulatorLauncher() { unsetenv("ZM_COTENANT_LAUNCHER"); }
  EmulatorLauncher(const EmulatorLauncher&) = delete;
  EmulatorLauncher& operator=(const EmulatorLauncher&) = delete;
  [[nodiscard]] static bool active() { return std::string(ZM_TEST_EMULATOR).size() > 0; }
};

// /proc/<pid>/maps (empty if unreadable).
inline std::string ProcMaps(const std::string& pid = "self") {
  std::ifstream in("/proc/" + pid + "/maps");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The permissions column of the mapping of `path` in `maps` ("r--s"), empty if not mapped.
inline std::string MappingPerms(const std::string& maps, const std::string& path) {
  std::istringstream in(maps);
  std::string line;
  while (std::getline(in, line)) {
    if (line.size() >= path.size() &&
        line.compare(line.size() - path.size(), path.size(), path) == 0) {
      std::istringstream f(line);
      std::string range, perms;
      f >> range >> perms;
      return perms;
    }
  }
  return {};
}

}  // namespace zm::test
