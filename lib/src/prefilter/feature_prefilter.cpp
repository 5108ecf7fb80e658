#include "prefilter/feature_prefilter.h"

#include "nl_means/nl_means.h"

namespace mcdn {

void prefilter_planes(std::vector<FeaturePlanes>& features, const PrefilterOptions& options,
                      int nthreads, const ConvergedTiles* skip)
{
    if (features.empty())
        return;
    const size_t n = features.size();

    // Step 1 (§5.1): A filtered with the weights of B, B with the weights of A. The guide's
    // variance is that of one half: variance_scale × variance of the mean.
    std::vector<const Plane*> image, guide, variance;
    for (const FeaturePlanes& f : features) {
        image.push_back(&f.half_a);
        guide.push_back(&f.half_b);
        variance.push_back(&f.variance);
    }
    for (const FeaturePlanes& f : features) {
        image.push_back(&f.half_b);
        guide.push_back(&f.half_a);
        variance.push_back(&f.variance);
    }
    NlMeansParams step1 { options.patch_radius, options.window_radius, options.k,
                          options.variance_scale };
    std::vector<Plane> halves = nl_means(image, guide, variance, step1, nthreads, skip);
    for (size_t i = 0; i < n; ++i) {
        features[i].half_a = std::move(halves[i]);
        features[i].half_b = std::move(halves[n + i]);
    }

    // Step 2: the squared difference of the filtered halves estimates their residual
    // variance; it guides the filtering of their mean.
    image.clear();
    variance.clear();
    for (FeaturePlanes& f : features) {
        for (size_t p = 0; p < f.mean.size(); ++p) {
            float a = f.half_a.px[p], b = f.half_b.px[p];
            f.mean.px[p] = 0.5f * (a + b);
            f.variance.px[p] = sanitize_variance(0.25f * (b - a) * (b - a));
        }
        image.push_back(&f.mean);
        variance.push_back(&f.variance);
    }
    NlMeansParams step2 { options.second_patch_radius, options.second_window_radius,
                          options.second_k, 1.0f };
    std::vector<Plane> means = nl_means(image, image, variance, step2, nthreads, skip);
    for (size_t i = 0; i < n; ++i)
        features[i].mean = std::move(means[i]);
}

}  // namespace mcdn
