#include "skip/constant_features.h"

#include <algorithm>

namespace mcdn {

bool is_constant_feature(const FeaturePlanes& f)
{
    if (f.mean.px.empty())
        return false;
    const float value = f.mean.px[0];
    auto all_equal = [value](const Plane& p) {
        return std::all_of(p.px.begin(), p.px.end(), [value](float v) { return v == value; });
    };
    return all_equal(f.mean) && all_equal(f.half_a) && all_equal(f.half_b);
}

int drop_constant_features(std::vector<FeaturePlanes>& features,
                           std::vector<FeatureChannel>* channels)
{
    size_t kept = 0;
    for (size_t i = 0; i < features.size(); ++i) {
        if (is_constant_feature(features[i]))
            continue;
        if (kept != i) {
            features[kept] = std::move(features[i]);
            if (channels)
                (*channels)[kept] = std::move((*channels)[i]);
        }
        ++kept;
    }
    const int removed = int(features.size() - kept);
    features.resize(kept);
    if (channels)
        channels->resize(kept);
    return removed;
}

}  // namespace mcdn
