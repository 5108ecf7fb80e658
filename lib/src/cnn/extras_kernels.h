// Extra AOVs through the beauty's KPCN kernels (core/extra_aovs.h says why). Each extra E is
// split like the colour C, with r = diffuse / colour clamped to [0, 1]: r·E goes through the
// diffuse kernels (demodulated like the diffuse), (1 − r)·E through the specular kernels
// (in linear space: the kernels are linear, the log of the specular branch is not). The
// beauty's denoised components D' and S' are then shared out in proportion,
//   E' = D' · K_d(r E) / K_d(r C) + S' · K_s((1 − r) E) / K_s((1 − r) C),
// which adds up to D' + S' (the denoised beauty) over extras that add up to C.
#pragma once

#include <vector>

#include "cnn/cnn_steps.h"
#include "core/extra_aovs.h"

namespace mcdn {
namespace kpcn {

/// Rows [first, last) of the image of a tile's `window` (branch_inputs wrote channels 0-2;
/// 3 × (2 + extras) channels in all): the parts the branch's kernels filter for the extras,
/// the colour's part, then each extra's (3 channels each; the diffuse parts demodulated).
/// `raw` covers inputs_rect of those rows; the extras' planes are the whole frame's.
void add_extra_parts(nn::Tensor& image, const RawPlanes& raw,
                     const std::vector<ExtraPlanes>& extras, Branch branch, const Rect& window,
                     int first, int last);

/// One branch's result on a tile: its denoised component on the tile's output rectangle
/// (3 planes, in the beauty's units) and the filtered image of the tile's window, whose
/// corner is `window` in the frame (the parts from channel 3 on).
struct BranchResult {
    Plane component[3];
    const nn::Tensor* filtered = nullptr;
    int window_x0 = 0, window_y0 = 0;
};

/// Writes each extra's share of the denoised components into its channels of `frame` on
/// `rect` (frame pixels, the rectangle of the components). `diffuse` is null without a
/// diffuse/specular split.
void write_extras(OutputFrame& frame, Rect rect, const std::vector<ExtraPlanes>& extras,
                  const BranchResult* diffuse, const BranchResult& specular);

}  // namespace kpcn
}  // namespace mcdn
