// A progress bar on stderr for long generation: a redrawn bar when stderr is a terminal, else a
// plain "label: N%" line every 10 percent (so logs stay readable). Disabled = silent. Progress is
// presentation only: nothing of it reaches the scenario files.
#pragma once

#include <cstdint>
#include <string>

namespace zm::sim {

class Progress {
 public:
  Progress(bool enabled, std::string label, std::uint64_t total);
  ~Progress();
  void Update(std::uint64_t done);
  void Finish();

 private:
  bool enabled_;
  bool tty_;
  std::string label_;
  std::uint64_t total_;
  int last_percent_ = -1;
  bool finished_ = false;
};

}  // namespace zm::sim
