#include "nfor/extras_regression.h"

#include <algorithm>

namespace mcdn {

namespace {

/// The fits of `in` with `image` in place of the beauty's, on this frame alone: the extras
/// of neighbouring frames are not read (nfor/neighbour_frames.h), and their frame-offset
/// feature goes with them.
std::vector<std::vector<Plane>> fit(RegressionInputs in, const Plane image[3], int nthreads)
{
    for (int c = 0; c < 3; ++c)
        in.image[c] = &image[c];
    if (!in.other_frames.empty()) {
        in.other_frames.clear();
        in.features.pop_back();
    }
    return collaborative_regression(in, nthreads);
}

}  // namespace

ExtraAovs::ExtraAovs(std::vector<ExtraPlanes> extras)
{
    for (ExtraPlanes& e : extras)
        m_extras.push_back({ std::move(e), {}, {}, {}, {} });
}

void ExtraAovs::first_pass(const RegressionInputs& first_a, const RegressionInputs& first_b,
                           int nthreads)
{
    for (Extra& e : m_extras) {
        e.fits_a = fit(first_a, e.planes.half_a, nthreads);
        e.fits_b = fit(first_b, e.planes.half_b, nthreads);
        for (int c = 0; c < 3; ++c)
            e.planes.half_a[c] = e.planes.half_b[c] = Plane();
    }
}

void ExtraAovs::first_pass_one_buffer(const RegressionInputs& first, int nthreads)
{
    for (Extra& e : m_extras)
        e.fits_a = fit(first, e.planes.mean, nthreads);
}

void ExtraAovs::blend(const std::vector<Plane>& selection)
{
    for (Extra& e : m_extras) {
        for (int c = 0; c < 3; ++c) {
            e.combined[c] = Plane(e.planes.mean[c].width, e.planes.mean[c].height);
            for (size_t i = 0; i < e.combined[c].size(); ++i) {
                const float s = selection[c].px[i];
                const float a = blend_candidates(e.fits_a.data(), c, i, s);
                const float b = e.fits_b.empty() ? a : blend_candidates(e.fits_b.data(), c, i, s);
                e.combined[c].px[i] = 0.5f * (a + b);
            }
        }
        e.fits_a.clear();
        e.fits_b.clear();
    }
}

void ExtraAovs::second_pass(const RegressionInputs& second, int nthreads)
{
    for (Extra& e : m_extras) {
        e.denoised = std::move(fit(second, e.combined, nthreads)[0]);
        for (int c = 0; c < 3; ++c) {
            e.combined[c] = Plane();
            for (size_t i = 0; i < e.denoised[c].size(); ++i)
                if (!std::isfinite(e.denoised[c].px[i]))
                    e.denoised[c].px[i] = e.planes.mean[c].px[i];
        }
    }
}

void ExtraAovs::blend_is_result()
{
    for (Extra& e : m_extras) {
        e.denoised.clear();
        for (int c = 0; c < 3; ++c) {
            e.denoised.push_back(std::move(e.combined[c]));
            for (size_t i = 0; i < e.denoised[c].size(); ++i)
                if (!std::isfinite(e.denoised[c].px[i]))
                    e.denoised[c].px[i] = e.planes.mean[c].px[i];
        }
    }
}

void ExtraAovs::share_rounding(const Plane color[3], const std::vector<Plane>& denoised_color)
{
    constexpr double kAddsUp = 1e-5;  // relative to the pixel's magnitude
    std::vector<std::string> partitions;
    for (const Extra& e : m_extras)
        if (std::find(partitions.begin(), partitions.end(), e.planes.partition) == partitions.end())
            partitions.push_back(e.planes.partition);
    std::vector<Extra*> set;
    for (const std::string& partition : partitions) {
        set.clear();
        for (Extra& e : m_extras)
            if (e.planes.partition == partition)
                set.push_back(&e);
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < color[c].size(); ++i) {
                double input_sum = 0, input_scale = std::abs(color[c].px[i]);
                double output_sum = 0, output_scale = 0;
                for (const Extra* e : set) {
                    input_sum += e->planes.mean[c].px[i];
                    input_scale += std::abs(e->planes.mean[c].px[i]);
                    output_sum += e->denoised[c].px[i];
                    output_scale += std::abs(e->denoised[c].px[i]);
                }
                if (!(std::abs(input_sum - color[c].px[i]) <= kAddsUp * input_scale)
                    || !(output_scale > 0))
                    continue;
                const double residual = denoised_color[c].px[i] - output_sum;
                for (Extra* e : set) {
                    float& v = e->denoised[c].px[i];
                    v = sanitize(float(v + residual * (std::abs(v) / output_scale)));
                }
            }
    }
}

void ExtraAovs::put_back_outliers(const OutlierPixels& outliers)
{
    for (size_t e = 0; e < m_extras.size() && e < outliers.extra_excess.size(); ++e)
        for (size_t k = 0; k < outliers.pixels.size(); ++k)
            for (int c = 0; c < 3; ++c)
                m_extras[e].denoised[c].px[outliers.pixels[k]] += outliers.extra_excess[e][k][c];
}

void ExtraAovs::pass_through(const ConvergedTiles& converged)
{
    for (Extra& e : m_extras)
        for (int c = 0; c < 3; ++c)
            pass_through_converged(e.denoised[c], e.planes.mean[c], converged);
}

void ExtraAovs::write(ImageBuf& dst, ROI roi) const
{
    for (const Extra& e : m_extras)
        for (int c = 0; c < 3; ++c)
            write_plane(dst, e.planes.channels[c], e.denoised[c], roi);
}

}  // namespace mcdn
