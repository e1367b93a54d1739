// The code's one stopwatch reading: milliseconds on the steady clock since a start point, for the
// stage times the reports carry. Include it from .cc files (an anonymous-namespace MsSince of
// another file must not meet it).
#pragma once

#include <chrono>

namespace zm {

// Milliseconds (fractional) from t0 to now on std::chrono::steady_clock.
[[nodiscard]] inline double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace zm
