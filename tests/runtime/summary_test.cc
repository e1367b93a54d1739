// summary.json's TimeTotal four ways (lib/runtime/summary.h, TimeTotalJson): the one derivation
// LoopSummary and the summary of a killed run share, on counts worked by hand.
#include "runtime/summary.h"

#include <doctest/doctest.h>

namespace zm {
namespace {

TEST_CASE("TimeTotal with and without the start-up tick and the idle-time loads") {
  // Four steady ticks averaging 10 ms, of which 8 ms in all were waits on idle-time loads; the
  // idle parts ran 40 ms of loads; the start-up tick took 1,000 ms.
  const nlohmann::json t = TimeTotalJson({.steady_mean_ms = 10.0,
                                          .steady_ticks = 4,
                                          .has_startup = true,
                                          .startup_tick_ms = 1000.0,
                                          .late_ms = 8.0,
                                          .idle_load_ms = 40.0});
  CHECK(t["steady"].get<double>() == doctest::Approx(10.0));
  CHECK(t["with_startup"].get<double>() == doctest::Approx((4 * 10.0 + 1000.0) / 5));  // 208
  CHECK(t["without_idle_loads"].get<double>() == doctest::Approx(10.0 - 2.0));
  CHECK(t["with_idle_loads"].get<double>() == doctest::Approx(10.0 - 2.0 + 10.0));
}

TEST_CASE("TimeTotal of a run that only had its start-up tick, and of none") {
  const nlohmann::json only = TimeTotalJson({.has_startup = true, .startup_tick_ms = 500.0});
  CHECK(only["steady"].get<double>() == 0.0);
  CHECK(only["with_startup"].get<double>() == doctest::Approx(500.0));
  CHECK(only["with_idle_loads"].get<double>() == 0.0);
  const nlohmann::json none = TimeTotalJson({});
  CHECK(none["with_startup"].get<double>() == 0.0);
}

}  // namespace
}  // namespace zm
