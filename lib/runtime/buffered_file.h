// One buffered output file for the streams a run writes line by line (ticks.jsonl, estimate.tum;
// the evaluation's device lines ride on ticks.jsonl): opened (truncated) once, a stdio buffer
// allocated once at Open, then Write() of pre-formatted bytes that never allocates, an explicit
// Flush() the caller times (every N ticks; every tick where a kill must leave every line), and
// Close(). The one place these files are opened, buffered, flushed and closed.
#pragma once

#include <cstddef>
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
  ~BufferedFile();

  // Opens (truncates) `path`; `what` names the file in the error ("telemetry file").
  [[nodiscard]] Status Open(const std::string& path, std::string_view what);
  [[nodiscard]] bool is_open() const { return file_ != nullptr; }
  // Appends `bytes` to the buffer (written out when it fills or at Flush). Never allocates;
  // false when closed or the write failed.
  bool Write(std::string_view bytes);
  void Flush();
  void Close();

 private:
  std::FILE* file_ = nullptr;
  char* stdio_buffer_ = nullptr;
};

}  // namespace zm
