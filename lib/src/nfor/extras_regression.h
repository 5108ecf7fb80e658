// Extra AOVs through the beauty's NFOR filters (core/extra_aovs.h says why), stage by stage
// alongside the beauty so that each stage's inputs are still there (nfor.cpp frees planes
// after their last use).
#pragma once

#include <vector>

#include "skip/converged_tiles.h"
#include "core/extra_aovs.h"
#include "outliers/outliers.h"
#include "nfor/regression.h"

namespace mcdn {

/// §5.3: the candidate fits blended by the selection map s ∈ [0, 1]: f0 + s (f1 − f0).
inline float blend_candidates(const std::vector<Plane> fits[2], int c, size_t i, float s)
{
    return fits[0][c].px[i] + s * (fits[1][c].px[i] - fits[0][c].px[i]);
}

class ExtraAovs {
public:
    explicit ExtraAovs(std::vector<ExtraPlanes> extras);
    bool empty() const { return m_extras.empty(); }

    /// §5.2: each extra's halves fitted by the beauty's first-pass regressions (their
    /// guides, variances, features and bandwidths; only the image differs).
    void first_pass(const RegressionInputs& first_a, const RegressionInputs& first_b, int nthreads);
    /// §5.2 without half buffers: each extra itself fitted by the beauty's regression of the
    /// render (nfor's one-buffer path).
    void first_pass_one_buffer(const RegressionInputs& first, int nthreads);
    /// §5.3: the candidates blended with the beauty's filtered selection map; the halves'
    /// average is what the second pass filters (the one fit, on the one-buffer path).
    void blend(const std::vector<Plane>& selection);
    /// §5.4: the beauty's second-pass regression (guided by its combined halves).
    void second_pass(const RegressionInputs& second, int nthreads);
    /// Without half buffers there is no second pass: the blend is the result.
    void blend_is_result();

    /// Linear in exact arithmetic, the regressions round their float sums differently for
    /// each AOV, and ill-conditioned windows amplify that (well above float epsilon of the
    /// beauty). Where the input of a set of extras (AovSet::Extra::partition: light groups,
    /// light passes) adds up to the beauty's (to 1e-5), the residual beauty − Σ set of the
    /// result is shared out in proportion to |extra|, so that they add up there as well.
    void share_rounding(const Plane color[3], const std::vector<Plane>& denoised_color);
    /// Adds each extra's share of the outliers' excess back at their pixels (after
    /// share_rounding, which sees the inputs without it).
    void put_back_outliers(const OutlierPixels& outliers);
    /// Each extra's result is its render on the converged tiles (mcdn/skip.h).
    void pass_through(const ConvergedTiles& converged);
    /// Writes each extra's result into its channels of dst inside roi.
    void write(ImageBuf& dst, ROI roi) const;

private:
    struct Extra {
        ExtraPlanes planes;
        std::vector<std::vector<Plane>> fits_a, fits_b;  // first pass, per bandwidth
        Plane combined[3];
        std::vector<Plane> denoised;
    };
    std::vector<Extra> m_extras;
};

}  // namespace mcdn
