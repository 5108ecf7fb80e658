#include "nfor/extras.h"

namespace mcdn {

namespace {

/// The candidate fits of `in` with `image` in place of the beauty's half.
std::vector<std::vector<Plane>> fit(RegressionInputs in, const Plane image[3], int nthreads)
{
    for (int c = 0; c < 3; ++c)
        in.image[c] = &image[c];
    return collaborative_regression(in, nthreads);
}

}  // namespace

std::vector<Plane> denoise_extra(const ExtraPlanes& extra, const BeautyFilters& beauty,
                                 int nthreads)
{
    std::vector<std::vector<Plane>> fits_a = fit(beauty.first_a, extra.half_a, nthreads);
    std::vector<std::vector<Plane>> fits_b = fit(beauty.first_b, extra.half_b, nthreads);
    Plane combined[3];
    for (int c = 0; c < 3; ++c) {
        combined[c] = Plane(extra.mean[c].width, extra.mean[c].height);
        for (size_t i = 0; i < combined[c].size(); ++i) {
            const float s = beauty.selection[c].px[i];
            combined[c].px[i] = 0.5f * (blend_candidates(fits_a.data(), c, i, s)
                                        + blend_candidates(fits_b.data(), c, i, s));
        }
    }
    fits_a.clear();
    fits_b.clear();
    std::vector<Plane> denoised = std::move(fit(beauty.second, combined, nthreads)[0]);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < denoised[c].size(); ++i)
            if (!std::isfinite(denoised[c].px[i]))
                denoised[c].px[i] = extra.mean[c].px[i];
    return denoised;
}

void share_rounding(std::vector<std::vector<Plane>>& denoised,
                    const std::vector<ExtraPlanes>& extras, const Plane colour[3],
                    const std::vector<Plane>& denoised_colour)
{
    constexpr double kAddsUp = 1e-5;  // relative to the pixel's magnitude
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < colour[c].size(); ++i) {
            double input_sum = 0, input_scale = std::abs(colour[c].px[i]);
            double output_sum = 0, output_scale = 0;
            for (size_t e = 0; e < extras.size(); ++e) {
                input_sum += extras[e].mean[c].px[i];
                input_scale += std::abs(extras[e].mean[c].px[i]);
                output_sum += denoised[e][c].px[i];
                output_scale += std::abs(denoised[e][c].px[i]);
            }
            if (!(std::abs(input_sum - colour[c].px[i]) <= kAddsUp * input_scale)
                || !(output_scale > 0))
                continue;
            const double residual = denoised_colour[c].px[i] - output_sum;
            for (size_t e = 0; e < extras.size(); ++e) {
                float& v = denoised[e][c].px[i];
                v = sanitize(float(v + residual * (std::abs(v) / output_scale)));
            }
        }
}

}  // namespace mcdn
