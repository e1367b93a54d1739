#include "runtime/frame_source.h"

#include <utility>

#include "runtime/frames_file.h"

namespace zm {
namespace {

class ReplayFrameSource final : public FrameSource {
 public:
  explicit ReplayFrameSource(FrameReader reader) : reader_(std::move(reader)) {}
  Result<bool> Next(Frame* frame) override { return reader_.Next(frame); }
  [[nodiscard]] std::uint32_t max_features() const override { return reader_.max_features(); }
  [[nodiscard]] Images images() const override {
    const FramesFileInfo& i = reader_.info();
    return {i.max_colour_bytes, i.image_width, i.image_height};
  }

 private:
  FrameReader reader_;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenReplaySource(const std::string& frames_path) {
  auto reader = FrameReader::Open(frames_path);
  if (!reader.ok()) return reader.status();
  return std::unique_ptr<FrameSource>(new ReplayFrameSource(std::move(reader).value()));
}

Result<bool> StagedFrameSource::Next(Frame* frame) {
  if (!ready_) return false;
  ready_ = false;
  std::swap(*frame, staged_);
  frame->index = next_index_++;
  return true;
}

}  // namespace zm
