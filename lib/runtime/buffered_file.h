// One buffered output file for the per-tick streams (ticks.jsonl, estimate.tum): a FILE* whose
// stdio buffer is allocated once at open, so a warm Write() never allocates and a daemon that runs
// for months keeps nothing but the buffer. The one implementation both writers use.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

#include "common/status.h"

namespace zm {

class BufferedFile {
 public:
  BufferedFile() = default;
  BufferedFile(const BufferedFile&) = delete;
  BufferedFile& operator=(const BufferedFile&) = delete;
  ~BufferedFile() { Close(); }

  // Opens (truncates) `path`; `what` names it in the error ("telemetry file"). Allocates the
  // stdio buffer (64 KiB), once.
  [[nodiscard]] Status Open(const std::string& path, std::string_view what);
  // Appends `bytes`. false when the file is not open or the write failed. Never allocates.
  bool Write(std::string_view bytes);
  void Flush();
  void Close();
  [[nodiscard]] bool is_open() const { return file_ != nullptr; }

 private:
  std::FILE* file_ = nullptr;
  char* buffer_ = nullptr;
};

}  // namespace zm
