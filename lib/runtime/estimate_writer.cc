#include "runtime/estimate_writer.h"

#include <Eigen/Geometry>

#include "runtime/text_line.h"

namespace zm {

Status EstimateWriter::Open(const std::string& path) {
  ZM_RETURN_IF_ERROR(file_.Open(path, "estimate file"));
  (void)file_.Write("# timestamp tx ty tz qx qy qz qw\n");
  return Status::Ok();
}

bool EstimateWriter::Write(double stamp_s, const Pose3& pose) {
  if (!file_.is_open()) return false;
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d& t = pose.translation();
  char line[256];
  TextLine l(line, sizeof line);
  l.Fixed(stamp_s, 6).Sp().Fixed(t.x(), 6).Sp().Fixed(t.y(), 6).Sp().Fixed(t.z(), 6);
  l.Sp().Fixed(q.x(), 9).Sp().Fixed(q.y(), 9).Sp().Fixed(q.z(), 9).Sp().Fixed(q.w(), 9).Char('\n');
  return l.ok() && file_.Write(l.view());
}

void EstimateWriter::Flush() { file_.Flush(); }
void EstimateWriter::Close() { file_.Close(); }

}  // namespace zm
