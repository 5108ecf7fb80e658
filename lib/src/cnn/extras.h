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
void add_extra_parts(nn::Tensor& image, const RawPlanes& raw, const std::vector<ExtraPlanes>& extras,
                     Branch branch, const nn::Region& window, int first, int last);

/// One branch's result: its denoised component (3 planes, in the beauty's units) and the
/// filtered image of with_extra_parts (the parts from channel 3 on).
struct BranchResult {
    Plane component[3];
    const nn::Tensor* filtered = nullptr;
};

/// Writes each extra's share of the denoised components into its channels of dst inside
/// roi. `diffuse` is null without a diffuse/specular split.
void write_extras(ImageBuf& dst, ROI roi, const std::vector<ExtraPlanes>& extras,
                  const BranchResult* diffuse, const BranchResult& specular);

}  // namespace kpcn
}  // namespace mcdn
