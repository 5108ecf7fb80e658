#include "prefilter/feature_prefilter.h"

#include "nl_means/nl_means.h"

namespace mcdn {

void prefilter_planes(std::vector<FeaturePlanes>& features, const PrefilterOptions& options,
                      int nthreads, const ConvergedTiles* skip)
{
    // A feature at a time (each has weights of its own): the filtered planes replace the
    // ones they were made from, so a feature's worth of planes is the extra memory.
    // Step 1 (§5.1): A filtered with the weights of B, B with the weights of A. The guide's
    // variance is that of one half: variance_scale × variance of the mean.
    const NlMeansParams step1 { options.patch_radius, options.window_radius, options.k,
                                options.variance_scale };
    const NlMeansParams step2 { options.second_patch_radius, options.second_window_radius,
                                options.second_k, 1.0f };
    for (FeaturePlanes& f : features) {
        std::vector<Plane> halves = nl_means({ &f.half_a, &f.half_b }, { &f.half_b, &f.half_a },
                                             { &f.variance, &f.variance }, step1, nthreads, skip);
        f.half_a = std::move(halves[0]);
        f.half_b = std::move(halves[1]);

        // Step 2: the squared difference of the filtered halves estimates their residual
        // variance; it guides the filtering of their mean (made here: the mean as read is
        // not used, and may not have been read).
        f.mean = Plane(f.half_a.width, f.half_a.height);
        for (size_t p = 0; p < f.mean.size(); ++p) {
            float a = f.half_a.px[p], b = f.half_b.px[p];
            f.mean.px[p] = 0.5f * (a + b);
            f.variance.px[p] = sanitize_variance(0.25f * (b - a) * (b - a));
        }
        f.mean = std::move(
            nl_means({ &f.mean }, { &f.mean }, { &f.variance }, step2, nthreads, skip)[0]);
    }
}

}  // namespace mcdn
