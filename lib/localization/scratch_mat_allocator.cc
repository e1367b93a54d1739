// See scratch_mat_allocator.h.
#include "localization/scratch_mat_allocator.h"

#include <opencv2/core/mat.hpp>

#include "arena/frame_scratch.h"

namespace zm {
namespace {

// cv::Mat's 64-byte alignment (CV_MALLOC_ALIGN), so SIMD paths see what they would see anyway.
constexpr std::size_t kMatAlign = 64;

class ScratchMatAllocator final : public cv::MatAllocator {
 public:
  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data0, size_t* step,
                         cv::AccessFlag /*flags*/,
                         cv::UMatUsageFlags /*usage*/) const override {
    // Row-major continuous layout, the steps filled from the innermost dimension outwards;
    // a caller's own data keeps its explicit steps.
    auto total = static_cast<std::size_t>(CV_ELEM_SIZE(type));
    for (int i = dims - 1; i >= 0; --i) {
      if (step != nullptr) {
        if (data0 != nullptr && step[i] != cv::Mat::AUTO_STEP) {
          CV_Assert(total <= step[i]);
          total = step[i];
        } else {
          step[i] = total;
        }
      }
      total *= static_cast<std::size_t>(sizes[i]);
    }
    auto* data = static_cast<uchar*>(data0);
    if (data == nullptr) {
      data = static_cast<uchar*>(ScratchAllocate(total, kMatAlign));
      if (data == nullptr) data = static_cast<uchar*>(cv::fastMalloc(total));
    }
    auto* u = new cv::UMatData(this);  // operator new: the scratch too, inside a scope
    u->data = u->origdata = data;
    u->size = total;
    if (data0 != nullptr) u->flags |= cv::UMatData::USER_ALLOCATED;
    return u;
  }

  bool allocate(cv::UMatData* u, cv::AccessFlag /*flags*/,
                cv::UMatUsageFlags /*usage*/) const override {
    return u != nullptr;
  }

  void deallocate(cv::UMatData* u) const override {
    if (u == nullptr) return;
    CV_Assert(u->urefcount == 0 && u->refcount == 0);
    if (!(u->flags & cv::UMatData::USER_ALLOCATED)) {
      if (!ScratchFree(u->origdata)) cv::fastFree(u->origdata);
      u->origdata = nullptr;
    }
    delete u;
  }
};

}  // namespace

void UseScratchForMatData() {
  // Never destroyed: Mats made with it may live until the process ends.
  static cv::MatAllocator* const allocator = [] {
    auto* a = new ScratchMatAllocator();
    cv::Mat::setDefaultAllocator(a);
    return a;
  }();
  (void)allocator;
}

}  // namespace zm
