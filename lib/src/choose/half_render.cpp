#include "choose/half_render.h"

#include <OpenImageIO/strutil.h>

#include "cnn/cnn_steps.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "mcdn/sure.h"
#include "skip/constant_features.h"
#include "sure/sure_steps.h"

namespace mcdn {

bool half_layout(HalfLayout& layout, const ImageSpec& in, const AovSet& aovs, Face face,
                 std::string& error)
{
    const std::vector<int>& color_half = aovs.channels(face_of(Role::Color, face));
    if (color_half.size() != 3 || !aovs.has(face_of(Role::Color, Face::HalfA))
        || !aovs.has(face_of(Role::Color, Face::HalfB))) {
        error = "the render has no half buffers of the colour";
        return false;
    }
    // Each channel's source and factor in src, -1: left out.
    std::vector<int> from(size_t(in.nchannels));
    std::vector<float> factor(size_t(in.nchannels), 1.0f);
    for (int c = 0; c < in.nchannels; ++c)
        from[size_t(c)] = c;
    std::vector<std::string> added = sure_channel_names(aovs, SureOptions());
    added.push_back(sure_channels::kFallback);
    for (const std::string& name : added)
        if (const int c = in.channelindex(name); c >= 0)
            from[size_t(c)] = -1;
    // Every half is left out: the colour's by its role, the rest by aov.h's naming (a half
    // of a channel no role reads would otherwise resolve as a role's half on dst).
    for (Face half : { Face::HalfA, Face::HalfB })
        for (int c : aovs.channels(face_of(Role::Color, half)))
            from[size_t(c)] = -1;
    for (int c = 0; c < in.nchannels; ++c)
        for (InputKind half : { InputKind::HalfA, InputKind::HalfB })
            if (OIIO::Strutil::starts_with(in.channelnames[size_t(c)], input_kind_prefix(half)))
                from[size_t(c)] = -1;
    const std::vector<int>& color = aovs.channels(Role::Color);
    for (size_t k = 0; k < 3; ++k)
        from[size_t(color[k])] = color_half[k];
    for (int c : aovs.channels(Role::ColorVariance))
        factor[size_t(c)] = 2.0f;
    // Every other role's and extra's channel with a half of aov.h's naming (what the chain
    // reads of the halves: mcdn/stages.h chain_input_selection), not other passes' (the
    // result must not depend on whether they were read).
    std::vector<bool> read(size_t(in.nchannels), false);
    for (int r = 0; r < kRoleCount; ++r)
        for (int c : aovs.channels(Role(r)))
            read[size_t(c)] = true;
    for (const AovSet::Extra& extra : aovs.extras())
        for (const std::vector<int>* channels : { &extra.channels, &extra.factor })
            for (int c : *channels)
                read[size_t(c)] = true;
    for (int c = 0; c < in.nchannels; ++c) {
        if (!read[size_t(c)])
            continue;
        const std::string& name = in.channelnames[size_t(c)];
        const int a = in.channelindex(input_kind_prefix(InputKind::HalfA) + name),
                  b = in.channelindex(input_kind_prefix(InputKind::HalfB) + name);
        if (a < 0 || b < 0 || from[size_t(c)] != c)
            continue;  // no half, or the colour's (by its role, above)
        from[size_t(c)] = face == Face::HalfA ? a : b;
        if (const int v = in.channelindex(input_kind_prefix(InputKind::Variance) + name); v >= 0)
            factor[size_t(v)] = 2.0f;
    }
    ImageSpec& spec = layout.spec;
    std::vector<std::pair<int, float>>& taken = layout.taken;
    spec = in;
    spec.set_format(OIIO::TypeDesc::FLOAT);
    spec.channelformats.clear();
    spec.channelnames.clear();
    taken.clear();
    spec.alpha_channel = spec.z_channel = -1;
    for (int c = 0; c < in.nchannels; ++c)
        if (from[size_t(c)] >= 0) {
            if (c == in.alpha_channel)
                spec.alpha_channel = int(taken.size());
            if (c == in.z_channel)
                spec.z_channel = int(taken.size());
            spec.channelnames.push_back(in.channelnames[size_t(c)]);
            taken.emplace_back(from[size_t(c)], factor[size_t(c)]);
        }
    spec.nchannels = int(taken.size());
    spec.erase_attribute(kInputsAttribute);
    return true;
}

bool half_render(OIIO::ImageBuf& dst, const OIIO::ImageBuf& src, const AovSet& aovs, Face face,
                 int nthreads, std::string& error)
{
    HalfLayout layout;
    if (!half_layout(layout, src.spec(), aovs, face, error))
        return false;
    const ImageSpec& in = src.spec();
    const ImageSpec& spec = layout.spec;
    const std::vector<std::pair<int, float>>& taken = layout.taken;
    if (!allocate_frame(dst, spec, false)) {
        error = "out of memory for a half of the render";
        return false;
    }
    const OIIO::ROI whole = src.roi();
    const int n = spec.nchannels;
    parallel_for_index(whole.height(), nthreads, [&](int r) {
        const int y = whole.ybegin + r;
        std::vector<float> row(size_t(whole.width()) * in.nchannels);
        src.get_pixels(OIIO::ROI(whole.xbegin, whole.xend, y, y + 1, 0, 1, 0, in.nchannels),
                       OIIO::TypeDesc::FLOAT, row.data());
        float* to = static_cast<float*>(dst.pixeladdr(whole.xbegin, y));
        for (int x = 0; x < whole.width(); ++x)
            for (int c = 0; c < n; ++c)
                to[size_t(x) * n + c] = row[size_t(x) * in.nchannels + taken[size_t(c)].first]
                                        * taken[size_t(c)].second;
    });
    return true;
}

FrameFacts render_facts(const OIIO::ImageBuf& src, const AovSet& aovs, const int render[3])
{
    FrameFacts facts;
    if (frame_facts(facts, src.spec()))
        return facts;
    facts.ybegin = src.roi().ybegin;
    facts.yend = src.roi().yend;
    const std::vector<int>& variance = aovs.channels(Role::ColorVariance);
    facts.color = color_sums(src, render, variance.size() == 3 ? variance.data() : nullptr);
    facts.has_exposure = true;
    facts.exposure = autoexposure(src, render);
    facts.has_depth = true;
    if (aovs.has(Role::Depth)) {
        const kpcn::DepthRange depth = kpcn::depth_range(src, aovs);
        facts.depth_lo = depth.lo;
        facts.depth_span = depth.hi - depth.lo;
    }
    facts.has_constant = true;
    std::vector<std::string> names = feature_channel_names(aovs, src.spec());
    for (const AovSet::Extra& extra : aovs.extras())
        for (const std::vector<int>* channels : { &extra.channels, &extra.half_a, &extra.half_b })
            for (int c : *channels)
                names.push_back(src.spec().channel_name(c));
    for (const std::string& name : names) {
        const Plane plane = read_plane(src, src.spec().channelindex(name));
        if (is_constant_plane(plane))
            facts.constant[name] = plane.px[0];
    }
    return facts;
}

}  // namespace mcdn
