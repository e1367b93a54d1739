// Stepping a driver (zonemapd's session, the tick loop) to its end, and counting what a warm
// window of its steps allocates: the loop makes no heap allocation once warm, and the tests of
// every driver check it the same way.
#pragma once

#include <doctest/doctest.h>

#include <cstdint>

#include "support/counting_allocator.h"

namespace zm::test {

// Calls `step()` (a Result<bool>: more to do) until it reports the end; an error fails the test.
// Returns the steps that had more to do.
template <typename Step>
int StepToEnd(Step&& step) {
  int steps = 0;
  for (;;) {
    auto more = step();
    REQUIRE_MESSAGE(more.ok(), more.status().ToString());
    if (!more.value()) return steps;
    ++steps;
  }
}

// What a warm window of a driver's steps allocated: `step()` (a Result<bool>: more to do) is
// called until it reports the end or an error; operator new and the malloc family are counted
// over exactly those steps.
struct StepAllocations {
  std::uint64_t steps = 0;
  std::uint64_t news = 0;
  std::uint64_t mallocs = 0;
};

template <typename Step>
StepAllocations CountStepAllocations(Step&& step) {
  StepAllocations out;
  const AllocationCounter news;
  const MallocCounter mallocs;
  for (;;) {
    auto more = step();
    if (!more.ok() || !more.value()) break;
    ++out.steps;
  }
  out.news = news.allocations();
  out.mallocs = mallocs.mallocs();
  return out;
}

}  // namespace zm::test
