// Elapsed time on the steady clock, in milliseconds: the one way zonemap times a step, a stage
// or a load (wall time, never the CPU's).
#pragma once

#include <chrono>

namespace zm {

// Milliseconds from t0 to now on std::chrono::steady_clock.
[[nodiscard]] inline double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace zm
