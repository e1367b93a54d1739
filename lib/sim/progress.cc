// Progress reporting on stderr (see progress.h).
#include "sim/progress.h"

#include <algorithm>
#include <cstdio>
#include <unistd.h>

namespace zm::sim {

Progress::Progress(bool enabled, std::string label, std::uint64_t total)
    : enabled_(enabled), tty_(enabled && isatty(STDERR_FILENO) != 0), label_(std::move(label)),
      total_(total) {}

Progress::~Progress() { Finish(); }

void Progress::Update(std::uint64_t done) {
  if (!enabled_ || finished_) return;
  const int percent = total_ == 0 ? 100 : static_cast<int>(100 * std::min(done, total_) / total_);
  if (tty_) {
    if (percent == last_percent_) return;
    constexpr int kWidth = 30;
    const int fill = percent * kWidth / 100;
    std::fprintf(stderr, "\r%-24s [%.*s%*s] %3d%%", label_.c_str(), fill,
                 "##############################", kWidth - fill, "", percent);
    std::fflush(stderr);
  } else {
    if (percent / 10 == last_percent_ / 10 && last_percent_ >= 0) return;
    std::fprintf(stderr, "%s: %d%%\n", label_.c_str(), percent / 10 * 10);
  }
  last_percent_ = percent;
}

void Progress::Finish() {
  if (!enabled_ || finished_) return;
  Update(total_);
  if (tty_) std::fprintf(stderr, "\n");
  finished_ = true;
}

}  // namespace zm::sim
