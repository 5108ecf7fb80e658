// The feature channels the NFOR stages read (prefilter §5.1, regression §5.2): every channel
// of albedo, normal, depth and visibility where present, plus extra features named by the
// user, each with its four faces (mean, variance of the mean, half buffers A and B).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

struct FeatureChannel {
    std::string name;  // channel name of the mean, for messages
    int mean = -1, variance = -1, half_a = -1, half_b = -1;  // -1: absent
};

/// Lists the feature channels. An extra feature is a channel name of the mean; its faces are
/// found as "variance.NAME", "A.NAME", "B.NAME". Fails (naming `op` and the channel) when
/// an extra feature is not in the buffer.
bool find_feature_channels(std::vector<FeatureChannel>& features, const AovSet& aovs,
                           const ImageSpec& spec, const std::vector<std::string>& extra_features,
                           const char* op, std::string& error);

/// The planes of one feature channel, sanitized. Missing faces are filled in: halves from the
/// mean (no cross-filtering possible), variance from the halves ((A - B)² / 4) or 0.
struct FeaturePlanes {
    Plane mean, variance, half_a, half_b;
};
FeaturePlanes read_feature(const OIIO::ImageBuf& src, const FeatureChannel& feature);
/// Which planes read_features fills besides the halves: a caller may leave the mean for later
/// (read_feature_means) or the variance out (left empty). A feature without halves of its own
/// has its mean read regardless (its halves are the mean).
struct FeatureFaces {
    bool mean = true, variance = true;
};
/// The planes of each of `features`, read in one pass over src's pixels.
std::vector<FeaturePlanes> read_features(const OIIO::ImageBuf& src,
                                         const std::vector<FeatureChannel>& features,
                                         FeatureFaces faces = {});
/// The means read_features left out (empty), in one pass; with `which`, only those of the
/// features it accepts.
void read_feature_means(std::vector<FeaturePlanes>& planes, const OIIO::ImageBuf& src,
                        const std::vector<FeatureChannel>& features,
                        const std::function<bool(const FeaturePlanes&)>& which = nullptr);

}  // namespace mcdn
