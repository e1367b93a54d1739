// Counting what a warm window of a driver's steps allocates (zonemapd's session, the tick loop):
// the loop makes no heap allocation once warm, and the tests of every driver check it the same way.
#pragma once

#include <cstdint>

#include "support/counting_allocator.h"

namespace zm::test {

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
