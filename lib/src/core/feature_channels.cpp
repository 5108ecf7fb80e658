#include "core/feature_channels.h"

#include <OpenImageIO/strutil.h>

namespace mcdn {

bool find_feature_channels(std::vector<FeatureChannel>& features, const AovSet& aovs,
                           const ImageSpec& spec, const std::vector<std::string>& extra_features,
                           const char* op, std::string& error)
{
    features.clear();
    for (Role base : { Role::Albedo, Role::Normal, Role::Depth, Role::Visibility }) {
        if (!aovs.has(base))
            continue;
        const auto& mean = aovs.channels(base);
        for (size_t i = 0; i < mean.size(); ++i) {
            FeatureChannel f;
            f.mean = mean[i];
            f.name = spec.channel_name(mean[i]);
            auto face = [&](Face which) {
                const auto& ch = aovs.channels(face_of(base, which));
                return i < ch.size() ? ch[i] : -1;
            };
            f.variance = face(Face::Variance);
            f.half_a = face(Face::HalfA);
            f.half_b = face(Face::HalfB);
            features.push_back(f);
        }
    }
    for (const std::string& name : extra_features) {
        FeatureChannel f;
        f.name = name;
        f.mean = spec.channelindex(name);
        if (f.mean < 0) {
            error = OIIO::Strutil::fmt::format(
                "{}: extra feature channel \"{}\" is not in the input (channels: {}); name a "
                "channel of the mean render",
                op, name, channel_list(spec));
            return false;
        }
        f.variance = spec.channelindex("variance." + name);
        f.half_a = spec.channelindex("A." + name);
        f.half_b = spec.channelindex("B." + name);
        features.push_back(f);
    }
    return true;
}

FeaturePlanes read_feature(const OIIO::ImageBuf& src, const FeatureChannel& feature)
{
    FeaturePlanes p;
    p.mean = read_plane(src, feature.mean);
    bool halves = feature.half_a >= 0 && feature.half_b >= 0;
    p.half_a = halves ? read_plane(src, feature.half_a) : p.mean;
    p.half_b = halves ? read_plane(src, feature.half_b) : p.mean;
    if (feature.variance >= 0) {
        p.variance = read_plane(src, feature.variance, true);
    } else {
        p.variance = Plane(p.mean.width, p.mean.height);
        for (size_t i = 0; i < p.variance.size(); ++i) {
            float d = p.half_a.px[i] - p.half_b.px[i];
            p.variance.px[i] = sanitize_variance(0.25f * d * d);
        }
    }
    return p;
}

}  // namespace mcdn
