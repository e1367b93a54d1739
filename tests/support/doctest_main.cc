// One main for every test executable. OpenCV's default thread pool can spin forever under
// qemu-user, and the tick loop is single-threaded anyway: pin OpenCV to the calling thread.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#if __has_include(<opencv2/core/utility.hpp>)
#include <opencv2/core/utility.hpp>
#define ZM_TEST_HAVE_OPENCV 1
#endif

int main(int argc, char** argv) {
#ifdef ZM_TEST_HAVE_OPENCV
  cv::setNumThreads(0);
#endif
  doctest::Context context(argc, argv);
  return context.run();
}
