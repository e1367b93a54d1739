#include "runtime/stop_signal.h"

#include <csignal>

namespace zm {
namespace {
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the flag is set from a signal handler");
extern "C" void ZmOnStopSignal(int) { g_stop.store(true, std::memory_order_relaxed); }
}  // namespace

void InstallStopSignals() {
  struct sigaction sa {};
  sa.sa_handler = ZmOnStopSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: blocking reads return EINTR
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool StopRequested() noexcept { return g_stop.load(std::memory_order_relaxed); }
const std::atomic<bool>* StopFlag() noexcept { return &g_stop; }
void RequestStop() noexcept { g_stop.store(true, std::memory_order_relaxed); }

}  // namespace zm
