// Outliers taken out of NFOR's and the KPCN's input (outliers.h says why and when).
#include "outliers/outliers.h"

#include <algorithm>
#include <cmath>

namespace mcdn {
namespace {

/// The values of the pixels around (x, y) within `radius`, without the pixel itself,
/// clipped to the plane, into `values`.
template <class Value>
void gather_neighbourhood(int x, int y, int width, int height, int radius, Value value,
                          std::vector<float>& values)
{
    values.clear();
    for (int v = std::max(0, y - radius); v <= std::min(height - 1, y + radius); ++v)
        for (int u = std::max(0, x - radius); u <= std::min(width - 1, x + radius); ++u)
            if (u != x || v != y)
                values.push_back(value(size_t(v) * width + u));
}

/// Their median (the lower one for an even count); reorders `values`.
float median(std::vector<float>& values)
{
    auto middle = values.begin() + (values.size() - 1) / 2;
    std::nth_element(values.begin(), middle, values.end());
    return *middle;
}

/// One outlier found: where, and the values that replace its inputs.
struct Found {
    uint32_t pixel;
    std::array<float, 3> mean, variance, half_a, half_b;
};

/// The mean of `values` without their `drop` largest (all of them when there are fewer);
/// reorders `values`.
float mean_without_largest(std::vector<float>& values, size_t drop)
{
    if (values.size() <= drop)
        return 0.0f;
    const auto end = values.end() - std::ptrdiff_t(drop);
    std::nth_element(values.begin(), end, values.end());
    double sum = 0;
    for (auto v = values.begin(); v != end; ++v)
        sum += *v;
    return float(sum / double(end - values.begin()));
}

}  // namespace

OutlierRule outlier_rule(float sigma, float variance_ratio, float level_ratio,
                         const ColorSums& frame)
{
    OutlierRule rule;
    rule.sigma = sigma;
    rule.variance_ratio = variance_ratio;
    rule.level_ratio = level_ratio;
    rule.level_floor =
        frame.n ? float(OutlierRule::kFloorOfMean * 3.0 * frame.sum_abs / double(frame.n)) : 0.0f;
    return rule;
}

OutlierPixels take_out_outliers(Plane mean[3], Plane variance[3], Plane* half_a, Plane* half_b,
                                std::vector<ExtraPlanes>& extras, const ConvergedTiles& converged,
                                const OutlierRule& rule, int nthreads)
{
    const int width = mean[0].width, height = mean[0].height, r = OutlierRule::radius;
    auto sum3 = [](const Plane* p, size_t i) { return p[0].px[i] + p[1].px[i] + p[2].px[i]; };
    std::vector<std::vector<Found>> rows(size_t(std::max(height, 0)));
    parallel_for_index(height, nthreads, [&](int y) {
        std::vector<float> scratch;
        for (int x = 0; x < width; ++x) {
            const size_t i = size_t(y) * width + x;
            if (converged.pixel(x, y))
                continue;
            // Cheap tests first: the pixel's variance must exceed the ratio times the
            // smallest of its neighbours' (the median is at least that).
            const float own_variance = sum3(variance, i);
            if (!(own_variance > 0.0f))
                continue;
            gather_neighbourhood(
                x, y, width, height, r, [&](size_t j) { return sum3(variance, j); }, scratch);
            if (scratch.empty()
                || !(own_variance
                     > rule.variance_ratio * *std::min_element(scratch.begin(), scratch.end())))
                continue;
            const float typical_variance = median(scratch);
            if (!(typical_variance > 0.0f && own_variance > rule.variance_ratio * typical_variance))
                continue;
            auto median_of = [&](auto value) {
                gather_neighbourhood(x, y, width, height, r, value, scratch);
                return median(scratch);
            };
            const float typical = median_of([&](size_t j) { return sum3(mean, j); });
            const float excess = sum3(mean, i) - typical;
            // The level against the neighbours' mean too (without their three largest, which
            // may be outliers of the same caustic): where most neighbours drew no sample of
            // a dim light (a sparse render), the median is near 0 while the mean is the
            // light, and the pixel is one of its samples. (scratch still holds the
            // neighbours' means that median_of gathered.)
            const float level = std::max(typical, mean_without_largest(scratch, 3));
            if (!(excess > rule.sigma * std::sqrt(typical_variance))
                || !(excess > rule.level_ratio * (level + rule.level_floor)))
                continue;
            if (half_a && half_b) {
                const float excess_a = sum3(half_a, i) - typical;
                const float excess_b = sum3(half_b, i) - typical;
                if (std::min(excess_a, excess_b) > 0.5f * std::max(excess_a, excess_b))
                    continue;
            }
            Found f { uint32_t(i), {}, {}, {}, {} };
            for (int c = 0; c < 3; ++c) {
                auto plane_median = [&](const Plane& p) {
                    return median_of([&](size_t j) { return p.px[j]; });
                };
                f.mean[c] = plane_median(mean[c]);
                f.variance[c] = plane_median(variance[c]);
                f.half_a[c] = half_a ? plane_median(half_a[c]) : 0.0f;
                f.half_b[c] = half_b ? plane_median(half_b[c]) : 0.0f;
            }
            rows[size_t(y)].push_back(f);
        }
    });

    // Replaced only now, so that every median was taken from the render as it came.
    OutlierPixels out;
    out.extra_excess.resize(extras.size());
    for (const std::vector<Found>& row : rows)
        for (const Found& f : row) {
            const size_t i = f.pixel;
            std::array<float, 3> excess;
            for (std::vector<std::array<float, 3>>& parts : out.extra_excess)
                parts.push_back({ 0.0f, 0.0f, 0.0f });
            for (int c = 0; c < 3; ++c) {
                excess[c] = mean[c].px[i] - f.mean[c];
                // Each extra gives up its share of the beauty's excess, so that extras which
                // add up to the beauty still do (and again once it is put back).
                for (size_t e = 0; e < extras.size(); ++e) {
                    const float share = std::fabs(mean[c].px[i]) > 0.0f
                                            ? extras[e].mean[c].px[i] / mean[c].px[i]
                                            : 0.0f;
                    const float part = share * excess[c];
                    out.extra_excess[e].back()[c] = part;
                    ExtraPlanes& x = extras[e];
                    x.mean[c].px[i] -= part;
                    if (!x.half_a[c].px.empty())
                        x.half_a[c].px[i] = x.half_b[c].px[i] = x.mean[c].px[i];
                }
                mean[c].px[i] = f.mean[c];
                variance[c].px[i] = f.variance[c];
                if (half_a && half_b) {
                    half_a[c].px[i] = f.half_a[c];
                    half_b[c].px[i] = f.half_b[c];
                }
            }
            out.pixels.push_back(f.pixel);
            out.excess.push_back(excess);
        }
    return out;
}

void put_back_outliers(const OutlierPixels& outliers, Plane denoised[3])
{
    for (size_t k = 0; k < outliers.pixels.size(); ++k)
        for (int c = 0; c < 3; ++c)
            denoised[c].px[outliers.pixels[k]] += outliers.excess[k][c];
}

}  // namespace mcdn
