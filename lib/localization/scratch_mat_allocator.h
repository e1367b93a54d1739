// OpenCV's Mat data inside a ScratchScope from the scope's FrameScratch (arena/frame_scratch.h).
//
// cv::ORB allocates its pyramid and descriptor matrices through cv::Mat, whose data comes from
// cv::fastMalloc (malloc), not operator new; the programs' operator new hook (zm_scratch_new)
// therefore cannot see it. UseScratchForMatData() makes this allocator OpenCV's default: inside
// a ScratchScope it takes the data from the region, outside one it is exactly OpenCV's standard
// allocator (cv::fastMalloc / cv::fastFree), so the rest of a program's Mats are unaffected.
// The setting is process-wide and installed once; the allocator is never destroyed (a Mat may
// outlive any object that would own it).
#pragma once

namespace zm {

void UseScratchForMatData();

}  // namespace zm
