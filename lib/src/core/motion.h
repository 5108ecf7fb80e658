// Frames aligned by motion vectors: for each pixel of a frame, where the surface it shows is
// in a neighbouring frame of the shot, and planes of that frame resampled onto this one's
// pixels (the spatio-temporal window of NFOR §8 sees its neighbours aligned).
//
// The motion role (mcdn/aov.h Role::Motion) holds Blender's Vector pass: (X, Y) towards the
// previous frame and (Z, W) from the next one, in pixels with y up; measured on Cycles'
// renders, the pixel p of frame t shows in frame t-1 what p + (X, -Y) shows, and in frame
// t+1 what p + (-Z, W) shows (OIIO rows, y down).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

/// A frame's motion as displacements in pixel rows (x right, y down).
struct FrameMotion {
    Plane to_previous[2], to_next[2];
};

/// The motion role of `frame` (resolved in `aovs`); false with `error` naming the channels
/// when the role is absent.
bool read_motion(FrameMotion& motion, const OIIO::ImageBuf& frame, const AovSet& aovs,
                 std::string& error);

/// For each pixel of frame t, the index of its pixel in frame t + offset, or -1 where the
/// motion leads outside that frame. `steps`: the motion of frames t, t±1, ..., t±(|offset|-1)
/// (nearest first), followed towards the previous frames when `backwards`. steps[0] may be a
/// band of frame t (rows of it), whose pixel (0, 0) is pixel `origin_x`, `origin_y` of the
/// other frames, which are whole, `width` × `height`. Positions are followed in real
/// numbers and rounded to a pixel at each step (nearest-neighbour: the resampled noise keeps
/// its variance, and no pixel mixes two surfaces).
struct FrameAlignment {
    int width = 0, height = 0;  // of steps[0]
    std::vector<int64_t> source;
    /// Fraction of the frame's pixels that land inside the other frame.
    double inside_fraction() const;
};
FrameAlignment align_frames(const std::vector<const FrameMotion*>& steps, bool backwards,
                            int origin_x, int origin_y, int width, int height);

/// `plane` of the other frame resampled onto this frame's pixels; `outside` where the
/// alignment leaves the other frame.
Plane warp(const Plane& plane, const FrameAlignment& alignment, float outside);

}  // namespace mcdn
