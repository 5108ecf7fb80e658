// mcdn::prefilter: the op face of the feature prefilter (feature_prefilter.cpp).
#include "mcdn/prefilter.h"

#include "core/frame_facts.h"
#include "skip/constant_features.h"
#include "skip/converged_tiles.h"
#include "core/feature_channels.h"
#include "ops/bands.h"
#include "core/op_prepare.h"
#include "core/progress.h"
#include "core/trace.h"
#include "mcdn/color.h"
#include "prefilter/feature_prefilter.h"

namespace mcdn {

namespace {

bool prefilter_in_working_space(ImageBuf& dst, const ImageBuf& src, const PrefilterOptions& options,
                                ROI roi, int nthreads, ProgressCounter& progress)
{
    const char* op = "prefilter";
    if (options.window_radius < 0 || options.patch_radius < 0 || options.second_window_radius < 0
        || options.second_patch_radius < 0 || !(options.k > 0) || !(options.second_k > 0)) {
        dst.errorfmt("prefilter: window and patch radii must be >= 0 and k > 0 (got window {}, "
                     "patch {}, k {})",
                     options.window_radius, options.patch_radius, options.k);
        return false;
    }
    StageTrace trace(op);
    AovSet aovs;
    std::vector<FeatureChannel> channels;
    std::string error;
    // Resolve against src before dst may be overwritten (dst may be src).
    if (!resolve_aovs(aovs, options.aovs, src.spec(), error)
        || !find_feature_channels(channels, aovs, src.spec(), options.extra_features, op, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    if (channels.empty()) {
        dst.errorfmt("prefilter: no feature channels (albedo, normal, depth, visibility) with "
                     "preset '{}' in the input ({}); check --aov:preset or name them with "
                     "aov overrides",
                     options.aovs.preset, channel_list(src.spec()));
        return false;
    }
    // §5.1 makes each mean from the filtered halves: the means are not read (but where they
    // may be constant, skip/constant_features.h).
    FeatureFaces faces;
    faces.mean = false;
    std::vector<FeaturePlanes> planes = read_features(src, channels, faces);
    read_means_of_constant_halves(planes, src, channels);
    const ConvergedTiles converged = converged_tiles_of(src, aovs, options.skip);
    if (options.skip.enabled)
        drop_constant_features(planes, channels, src.spec());  // copied unchanged
    trace.mark("read planes");
    if (!prepare_op(dst, src, options.aovs, aovs, op, nthreads))
        return false;
    trace.mark("copy src to dst");
    prefilter_planes(planes, options, nthreads, &converged);
    trace.mark("NL-means (5.1)");

    roi = output_roi(dst, roi);
    std::vector<PlaneWrite> writes;
    for (size_t i = 0; i < channels.size(); ++i) {
        writes.push_back({ channels[i].mean, &planes[i].mean });
        if (channels[i].half_a >= 0)
            writes.push_back({ channels[i].half_a, &planes[i].half_a });
        if (channels[i].half_b >= 0)
            writes.push_back({ channels[i].half_b, &planes[i].half_b });
        if (channels[i].variance >= 0)
            writes.push_back({ channels[i].variance, &planes[i].variance });
    }
    write_planes(dst, writes, roi);
    dst.specmod().attribute("mcdn:prefiltered", 1);
    trace.mark("write");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    return true;
}

}  // namespace

// How far the two NL-means steps reach: window plus patch, twice.
int receptive_radius(const PrefilterOptions& o)
{
    return o.window_radius + o.patch_radius + o.second_window_radius + o.second_patch_radius;
}

bool prefilter(ImageBuf& dst, const ImageBuf& src, const PrefilterOptions& options, ROI roi,
               int nthreads)
{
    if (!check_op_threads(dst, nthreads, "prefilter"))
        return false;
    // A chain's band (core/frame_facts.h) runs whole.
    const int64_t band_pixels = is_frame_band(src.spec()) ? 0 : options.band_pixels;
    ProgressCounter progress(options.progress, "prefilter",
                             band_count(src.roi(), receptive_radius(options), band_pixels));
    return run_local_op(dst, src, options.aovs, "prefilter", receptive_radius(options), band_pixels,
                        [&](ImageBuf& d, const ImageBuf& s) {
                            return prefilter_in_working_space(d, s, options, roi, nthreads,
                                                              progress);
                        });
}

ImageBuf prefilter(const ImageBuf& src, const PrefilterOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    prefilter(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
