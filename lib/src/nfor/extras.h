// Extra AOVs through the beauty's NFOR filters (core/extra_aovs.h says why).
#pragma once

#include <vector>

#include "core/extra_aovs.h"
#include "nfor/regression.h"

namespace mcdn {

/// §5.3: the candidate fits blended by the selection map s ∈ [0, 1]: f0 + s (f1 − f0).
inline float blend_candidates(const std::vector<Plane> fits[2], int c, size_t i, float s)
{
    return fits[0][c].px[i] + s * (fits[1][c].px[i] - fits[0][c].px[i]);
}

/// What the beauty went through: the first-pass regressions of each half (guides, variances,
/// features, bandwidths; their images are replaced), the filtered selection map, the second
/// pass (guided by the beauty's combined halves).
struct BeautyFilters {
    const RegressionInputs& first_a;
    const RegressionInputs& first_b;
    const std::vector<Plane>& selection;
    const RegressionInputs& second;
};

/// Fits the extra's halves like the beauty's (§5.2), blends the candidates with the beauty's
/// selection (§5.3) and filters their average in the second pass (§5.4). Every step is
/// linear in the extra.
std::vector<Plane> denoise_extra(const ExtraPlanes& extra, const BeautyFilters& beauty,
                                 int nthreads);

/// Linear in exact arithmetic, the regressions round their float sums differently for each
/// AOV, and ill-conditioned windows amplify that (up to ~4e-3 of the beauty on the box
/// fixture). Where the extras' input adds up to the beauty's (to 1e-5), the residual
/// beauty − Σ extras of the result is shared out in proportion to |extra|, so that they add
/// up there as well. `denoised[e]` holds extra e's result.
void share_rounding(std::vector<std::vector<Plane>>& denoised,
                    const std::vector<ExtraPlanes>& extras, const Plane colour[3],
                    const std::vector<Plane>& denoised_colour);

}  // namespace mcdn
