#pragma once
// libcamera cameras ("libcamera:" for the first camera, "libcamera:<id>" with the id `cam -l` and
// `tirstrain cameras` print, or any unique part of it such as "libcamera:Sensor B").
//
// The stream is configured for the requested size and pixel format; libcamera may adjust both to what the
// pipeline can do (vimc turns 640x480 into a multiple of its scaler steps): the size actually streamed is
// read back into settings() (width_px, height_px, and requested_size/size_adjusted when it differs), never
// hidden. Frames carry the buffer's sequence number (a jump marks kGapBefore with the number lost) and its
// timestamp (ns, CLOCK_MONOTONIC); a buffer whose metadata says FrameError comes out kIncomplete. Colour
// formats (RGB888, BGR888, XRGB8888, YUYV) are converted to grey; R8 and R16 are taken as they are. The
// destructor stops the camera (cancelling pending requests) and releases it.
//
// libcamera's headers are C++17 and stay inside libcamera_source.cpp.
#include <memory>
#include <string>
#include <vector>

#include "capture/aravis_source.hpp"  // CameraInfo
#include "capture/frame_source.hpp"

namespace tirstrain::capture {

// Cameras libcamera's pipeline handlers find (starts and stops a camera manager).
std::vector<CameraInfo> list_libcamera_cameras();

std::unique_ptr<FrameSource> open_libcamera_source(const std::string& id, const CameraSettings& settings);

}  // namespace tirstrain::capture
