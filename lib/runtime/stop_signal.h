// SIGINT/SIGTERM: the one handler every zonemap program installs. It only sets a flag; loops
// check it at a tick boundary, then flush what they write and exit normally. No SA_RESTART, so a
// read blocked on stdin or a socket returns EINTR and the loop sees the flag at once.
#pragma once

#include <atomic>

namespace zm {

// Installs the handlers (idempotent). Start-up only.
void InstallStopSignals();
// True once SIGINT or SIGTERM arrived (or RequestStop() was called).
[[nodiscard]] bool StopRequested() noexcept;
// The flag itself, for APIs that take `const std::atomic<bool>*`.
[[nodiscard]] const std::atomic<bool>* StopFlag() noexcept;
// Sets the flag from code (tests, a supervisor thread).
void RequestStop() noexcept;

}  // namespace zm
