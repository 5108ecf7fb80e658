// Frames aligned by motion vectors: for each pixel of a frame, where the surface it shows is
// in a neighbouring frame of the shot, and planes of that frame resampled onto this one's
// pixels (the spatio-temporal window of NFOR §8 sees its neighbours aligned).
//
// The motion role (mcdn/aov.h Role::Motion) holds Blender's Vector pass: (X, Y) towards the
// previous frame and (Z, W) from the next one, in pixels with y up; measured on Cycles'
// renders, the pixel p of frame t shows in frame t-1 what p + (X, -Y) shows, and in frame
// t+1 what p + (-Z, W) shows (OIIO rows, y down). RenderMan's backward and forward
// (motionBack, motionFore) are those displacements as they are (aov/presets.h
// preset_motion_signs).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

/// A frame's motion as displacements in pixel rows (x right, y down).
/// Most neighbouring frames on each side a cross-frame mode takes.
constexpr int kMaxNeighbourFrames = 4;

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
};
FrameAlignment align_frames(const std::vector<const FrameMotion*>& steps, bool backwards,
                            int origin_x, int origin_y, int width, int height);

/// `plane` of the other frame resampled onto this frame's pixels; `outside` where the
/// alignment leaves the other frame.
Plane warp(const Plane& plane, const FrameAlignment& alignment, float outside);

/// A neighbouring frame as the cross-frame modes take it: in the working space
/// (mcdn/color.h), its roles resolved, and where each pixel of this frame is in it.
struct AlignedFrame {
    int offset = 0;                             // frame number relative to this frame
    std::string name;                           // the file, for messages
    const OIIO::ImageBuf* frame = nullptr;      // the frame itself, or *converted
    std::unique_ptr<OIIO::ImageBuf> converted;  // a copy in the working space, if needed
    AovSet aovs;
    FrameAlignment alignment;
    /// "cross-frame: frame -1 (shot.0009.exr): <why>".
    std::string error(const std::string& why) const;
};

/// Checks, converts and aligns `previous` (frames t-1, t-2, ..., nearest first) and `next`
/// (t+1, ...) to src (whose roles are `src_aovs`) by the motion vectors of src and of the
/// frames between. Each must hold the roles `required` and src's data window (or src is a
/// band of rows of it: a chain's band, a SURE probe), and no side more than
/// kMaxNeighbourFrames. False with `error` naming the frame and what it lacks. Nothing is
/// copied unless a frame is not in the working space.
bool align_neighbours(std::vector<AlignedFrame>& frames, const OIIO::ImageBuf& src,
                      const AovSet& src_aovs, const AovSpec& spec,
                      const std::vector<const OIIO::ImageBuf*>& previous,
                      const std::vector<const OIIO::ImageBuf*>& next,
                      const std::vector<Role>& required, std::string& error);

}  // namespace mcdn
