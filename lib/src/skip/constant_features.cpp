#include "skip/constant_features.h"

#include <algorithm>

#include "core/frame_facts.h"

namespace mcdn {

bool is_constant_plane(const Plane& p)
{
    if (p.px.empty())
        return false;
    const float value = p.px[0];
    return std::all_of(p.px.begin(), p.px.end(), [value](float v) { return v == value; });
}

bool is_constant_feature(const FeaturePlanes& f)
{
    return is_constant_plane(f.mean) && is_constant_plane(f.half_a) && is_constant_plane(f.half_b)
           && f.half_a.px[0] == f.mean.px[0] && f.half_b.px[0] == f.mean.px[0];
}

void read_means_of_constant_halves(std::vector<FeaturePlanes>& features, const OIIO::ImageBuf& src,
                                   const std::vector<FeatureChannel>& channels)
{
    read_feature_means(features, src, channels, [](const FeaturePlanes& f) {
        return is_constant_plane(f.half_a) && is_constant_plane(f.half_b)
               && f.half_a.px[0] == f.half_b.px[0];
    });
}

namespace {

template <class Constant>
int drop_features(std::vector<FeaturePlanes>& features, std::vector<FeatureChannel>* channels,
                  const Constant& is_constant)
{
    size_t kept = 0;
    for (size_t i = 0; i < features.size(); ++i) {
        if (is_constant(i))
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

}  // namespace

int drop_constant_features(std::vector<FeaturePlanes>& features,
                           std::vector<FeatureChannel>* channels)
{
    return drop_features(features, channels,
                         [&](size_t i) { return is_constant_feature(features[i]); });
}

int drop_constant_features(std::vector<FeaturePlanes>& features,
                           std::vector<FeatureChannel>& channels, const OIIO::ImageSpec& spec)
{
    FrameFacts facts;
    if (!frame_facts(facts, spec) || !facts.has_constant)
        return drop_constant_features(features, &channels);
    // The faces read_feature fills in from the mean (a missing half) are the mean's.
    return drop_features(features, &channels, [&](size_t i) {
        const FeatureChannel& f = channels[i];
        auto mean = facts.constant.find(spec.channel_name(f.mean));
        if (mean == facts.constant.end())
            return false;
        if (f.half_a < 0 || f.half_b < 0)
            return true;
        for (int half : { f.half_a, f.half_b }) {
            auto h = facts.constant.find(spec.channel_name(half));
            if (h == facts.constant.end() || !(h->second == mean->second))
                return false;
        }
        return true;
    });
}

}  // namespace mcdn
