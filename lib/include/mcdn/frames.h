// Cross-frame input for any chain (issue 23): a frame and its neighbouring frames of the
// shot, aligned by the motion vectors, combined into one render of more samples where they
// agree. Arnold's noice denoises with NL-means over ±N frames; this takes the same idea one
// step earlier: the weight of a neighbour's pixel is the NL-means weight of its aligned
// patch against this frame's (the colour, its variance, a 7×7 patch; without a variance, as
// Cycles writes none, one estimated from the frames' agreement), and every noisy light
// channel (the colour, its halves, Blender's light passes, extra AOVs) becomes the weighted
// mean over the frames, its variance the weighted variance of that mean. The stage after it
// (the CNN, NFOR, SURE and the mix) then sees a render with up to 2N+1 times the samples
// where the frames agree, and this frame's own where they do not (a disocclusion, a moving
// highlight, the motion leaving the frame). Features and motion stay this frame's.
#pragma once

#include <functional>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"

namespace mcdn {

struct CombineFramesOptions {
    AovSpec aovs;
    /// The neighbouring frames, nearest first (t-1, t-2, ... and t+1, t+2, ...; at most 4
    /// each), each with the channels combined and the motion role (mcdn/aov.h), and src's
    /// data window (or src is a band of its rows). Read, never written.
    std::vector<const ImageBuf*> previous_frames, next_frames;
    /// NL-means patch radius and bandwidth of the frames' weights: a pixel of another
    /// frame weighs exp(-max(0, d²) / k²), d² the patch's variance-normalised distance.
    int patch_radius = 3;
    float k = 1.0f;
};

/// Whether the frames are weighed by a variance the render measured (the colour's variance
/// or its halves); else by one estimated from how well the frames agree with each other
/// (and this frame with itself, pixel to pixel), which front ends say with -v.
bool frames_have_measured_variance(const AovSet& aovs);

/// dst = src with its noisy light channels combined over the frames (inside `roi`; every
/// other channel kept). With no neighbours dst = src. Output finite and identical for any
/// thread count.
bool combine_frames(ImageBuf& dst, const ImageBuf& src, const CombineFramesOptions& options,
                    ROI roi = {}, int nthreads = 0);
ImageBuf combine_frames(const ImageBuf& src, const CombineFramesOptions& options, ROI roi = {},
                        int nthreads = 0);

/// A denoiser of the combined frames as a denoiser of this frame (mcdntool --cnn:frames=2):
/// dst = denoiser(combine_frames(src)) with every channel combine_frames changed back to
/// src's own, except the colour and the extra AOVs the denoiser wrote. The render's
/// variance, halves and light passes stay what the renderer wrote, which is what SURE and
/// the mix read of the render (a denoiser that sees more samples, of a render that has its
/// own). Errors on dst.
bool denoise_with_frames(ImageBuf& dst, const ImageBuf& src, const CombineFramesOptions& options,
                         const std::function<bool(ImageBuf&, const ImageBuf&)>& denoiser,
                         int nthreads = 0);

}  // namespace mcdn
