// The estimate, streamed: one TUM line per processed frame (`stamp tx ty tz qx qy qz qw`, the
// corrected body pose in the map frame), written through a BufferedFile (buffer set once at
// open), so a daemon that runs for months keeps no trajectory in memory and a warm Write() never
// allocates.
#pragma once

#include <string>

#include "common/status.h"
#include "geometry/pose.h"
#include "runtime/buffered_file.h"

namespace zm {

class EstimateWriter {
 public:
  EstimateWriter() = default;
  EstimateWriter(const EstimateWriter&) = delete;
  EstimateWriter& operator=(const EstimateWriter&) = delete;

  // Opens (truncates) `path` and writes the TUM header comment.
  [[nodiscard]] Status Open(const std::string& path);
  // One line. Never allocates; false if the write failed.
  bool Write(double stamp_s, const Pose3& pose);
  void Flush();
  void Close();

 private:
  BufferedFile file_;
};

}  // namespace zm
