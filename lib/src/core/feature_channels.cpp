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

std::vector<FeaturePlanes> read_features(const OIIO::ImageBuf& src,
                                         const std::vector<FeatureChannel>& features,
                                         FeatureFaces faces)
{
    std::vector<FeaturePlanes> planes(features.size());
    std::vector<PlaneRead> reads;
    for (size_t i = 0; i < features.size(); ++i) {
        const FeatureChannel& f = features[i];
        FeaturePlanes& p = planes[i];
        const bool halves = f.half_a >= 0 && f.half_b >= 0;
        if (faces.mean || !halves)
            reads.push_back({ f.mean, &p.mean });
        if (halves) {
            reads.push_back({ f.half_a, &p.half_a });
            reads.push_back({ f.half_b, &p.half_b });
        }
        if (faces.variance && f.variance >= 0)
            reads.push_back({ f.variance, &p.variance, true });
    }
    read_planes(src, reads);
    for (size_t i = 0; i < features.size(); ++i) {
        const FeatureChannel& f = features[i];
        FeaturePlanes& p = planes[i];
        if (f.half_a < 0 || f.half_b < 0)
            p.half_a = p.half_b = p.mean;
        if (faces.variance && f.variance < 0) {
            p.variance = Plane(p.half_a.width, p.half_a.height);
            for (size_t j = 0; j < p.variance.size(); ++j) {
                float d = p.half_a.px[j] - p.half_b.px[j];
                p.variance.px[j] = sanitize_variance(0.25f * d * d);
            }
        }
    }
    return planes;
}

void read_feature_means(std::vector<FeaturePlanes>& planes, const OIIO::ImageBuf& src,
                        const std::vector<FeatureChannel>& features,
                        const std::function<bool(const FeaturePlanes&)>& which)
{
    std::vector<PlaneRead> reads;
    for (size_t i = 0; i < features.size(); ++i)
        if (planes[i].mean.px.empty() && (!which || which(planes[i])))
            reads.push_back({ features[i].mean, &planes[i].mean });
    if (!reads.empty())
        read_planes(src, reads);
}

FeaturePlanes read_feature(const OIIO::ImageBuf& src, const FeatureChannel& feature)
{
    return std::move(read_features(src, { feature })[0]);
}

}  // namespace mcdn
