#include "nfor/neighbour_frames.h"

#include "core/motion.h"
#include "mcdn/color.h"

namespace mcdn {

namespace {

/// Far from any colour: a patch that reaches a pixel outside the aligned frame gets
/// distance kDistanceClamp there, and weight 0.
constexpr float kOutsideGuide = 1e10f;

/// `frame` in the working space (mcdn/color.h): itself, or a converted copy in `storage`.
bool in_working_space(const ImageBuf*& frame, ImageBuf& storage, const AovSpec& spec,
                      const AovSet& aovs, std::string& error)
{
    std::string from, why;
    if (!input_colorspace(from, why, spec, frame->spec(), error))
        return false;
    if (from == working_colorspace())
        return true;
    storage = frame->copy(OIIO::TypeDesc::FLOAT);
    if (!convert_color_channels(storage, aovs, from, working_colorspace(), error))
        return false;
    frame = &storage;
    return true;
}

/// src's rows lie inside the frame's data window, which has src's columns.
bool holds_rows_of(const ImageSpec& frame, const ImageSpec& src)
{
    return frame.x == src.x && frame.width == src.width && src.y >= frame.y
           && src.y + src.height <= frame.y + frame.height;
}

/// src's feature channels found by name in the frame; false with `missing` naming one.
bool features_in(std::vector<FeatureChannel>& out, const std::vector<FeatureChannel>& features,
                 const ImageSpec& src, const ImageSpec& frame, std::string& missing)
{
    for (FeatureChannel f : features) {
        for (int* index : { &f.mean, &f.variance, &f.half_a, &f.half_b })
            if (*index >= 0) {
                const std::string& name = src.channelnames[size_t(*index)];
                *index = frame.channelindex(name);
                if (*index < 0) {
                    missing = name;
                    return false;
                }
            }
        out.push_back(f);
    }
    return true;
}

/// Reads one frame's planes in its own pixels: colour, outliers out, prefiltered features.
void read_frame(NeighbourFrame& f, const ImageBuf& frame, const AovSet& aovs,
                const std::vector<FeatureChannel>& features, const NeighbourReading& r,
                int nthreads)
{
    read_color_planes(f.color, frame, aovs, r.halves);
    for (const FeatureChannel& c : features)
        f.features.push_back(read_feature(frame, c));
    if (r.outliers) {
        std::vector<ExtraPlanes> no_extras;
        take_out_outliers(f.color.mean, f.color.variance, r.halves ? f.color.half_a : nullptr,
                          r.halves ? f.color.half_b : nullptr, no_extras, ConvergedTiles {},
                          r.outlier_rule, nthreads);
    }
    const bool prefiltered = frame.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    if (r.prefilter && !prefiltered)
        prefilter_planes(f.features, r.prefilter_options, nthreads);
    for (FeaturePlanes& p : f.features)
        p.variance = Plane();
}

/// The frame's planes resampled onto this frame's pixels.
void align(NeighbourFrame& f, const FrameAlignment& a, bool halves)
{
    for (int c = 0; c < 3; ++c) {
        // Guides (the halves cross-guide, the mean guides itself) are far off outside.
        f.color.mean[c] = warp(f.color.mean[c], a, kOutsideGuide);
        f.color.variance[c] = warp(f.color.variance[c], a, 0.0f);
        if (halves) {
            f.color.half_a[c] = warp(f.color.half_a[c], a, kOutsideGuide);
            f.color.half_b[c] = warp(f.color.half_b[c], a, kOutsideGuide);
        }
    }
    for (FeaturePlanes& p : f.features) {
        p.mean = warp(p.mean, a, 0.0f);
        p.half_a = warp(p.half_a, a, 0.0f);
        p.half_b = warp(p.half_b, a, 0.0f);
    }
    f.offset_feature = Plane(a.width, a.height, float(f.offset));
    f.inside = a.inside_fraction();
}

const Plane* face(const ColorPlanes& c, FirstPassFace f, int channel)
{
    return f == FirstPassFace::HalfA   ? &c.half_a[channel]
           : f == FirstPassFace::HalfB ? &c.half_b[channel]
                                       : &c.mean[channel];
}

const Plane* face(const FeaturePlanes& p, FirstPassFace f)
{
    return f == FirstPassFace::HalfA ? &p.half_a : f == FirstPassFace::HalfB ? &p.half_b : &p.mean;
}

}  // namespace

void read_color_planes(ColorPlanes& color, const ImageBuf& src, const AovSet& aovs, bool halves)
{
    for (int c = 0; c < 3; ++c) {
        color.mean[c] = read_plane(src, aovs.channels(Role::Color)[c]);
        if (halves) {
            color.half_a[c] = read_plane(src, aovs.channels(Role::ColorA)[c]);
            color.half_b[c] = read_plane(src, aovs.channels(Role::ColorB)[c]);
        }
        if (aovs.has(Role::ColorVariance)) {
            color.variance[c] = read_plane(src, aovs.channels(Role::ColorVariance)[c], true);
        } else {  // two-buffer estimate of the variance of the mean
            color.variance[c] = Plane(src.spec().width, src.spec().height);
            for (size_t i = 0; i < color.variance[c].size(); ++i) {
                float d = color.half_a[c].px[i] - color.half_b[c].px[i];
                color.variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
}

bool read_neighbour_frames(std::vector<NeighbourFrame>& frames, const ImageBuf& src,
                           const std::vector<const ImageBuf*>& previous,
                           const std::vector<const ImageBuf*>& next,
                           const NeighbourReading& reading, int nthreads, std::string& error)
{
    FrameMotion own;
    if (!read_motion(own, src, *reading.aovs, error)) {
        error = "cross-frame: " + error;
        return false;
    }
    for (bool backwards : { true, false }) {
        const std::vector<const ImageBuf*>& side = backwards ? previous : next;
        std::vector<FrameMotion> motions;  // of the frames between
        motions.reserve(side.size());
        std::vector<const FrameMotion*> steps { &own };
        for (size_t k = 0; k < side.size(); ++k) {
            const int offset = backwards ? -int(k + 1) : int(k + 1);
            const ImageBuf* frame = side[k];
            const std::string name = frame->name().empty() ? std::string("in memory")
                                                           : std::string(frame->name());
            auto failed = [&](const std::string& why) {
                error = OIIO::Strutil::fmt::format("cross-frame: frame {:+d} ({}): {}", offset,
                                                   name, why);
                return false;
            };
            const ImageSpec& spec = frame->spec();
            if (!holds_rows_of(spec, src.spec()))
                return failed(OIIO::Strutil::fmt::format(
                    "its data window {}x{}+{}+{} does not hold this frame's {}x{}+{}+{}",
                    spec.width, spec.height, spec.x, spec.y, src.spec().width,
                    src.spec().height, src.spec().x, src.spec().y));
            AovSet aovs;
            std::vector<FeatureChannel> features;
            std::string missing;
            if (!resolve_aovs(aovs, *reading.spec, spec, error)
                || !aovs.require({ Role::Color, Role::Motion }, spec, error)
                || (reading.halves && !aovs.require({ Role::ColorA, Role::ColorB }, spec, error))
                || (!reading.halves && !aovs.require({ Role::ColorVariance }, spec, error)))
                return failed(error);
            if (!features_in(features, *reading.features, src.spec(), spec, missing))
                return failed("no channel " + missing);
            ImageBuf converted;
            if (!in_working_space(frame, converted, *reading.spec, aovs, error))
                return failed(error);
            NeighbourFrame f;
            f.offset = offset;
            read_frame(f, *frame, aovs, features, reading, nthreads);
            align(f, align_frames(steps, backwards, src.spec().x - spec.x,
                                  src.spec().y - spec.y, spec.width, spec.height),
                  reading.halves);
            frames.push_back(std::move(f));
            if (k + 1 < side.size()) {  // its motion leads to the next one out
                motions.emplace_back();
                if (!read_motion(motions.back(), *frame, aovs, error)) {
                    error = OIIO::Strutil::fmt::format("cross-frame: frame {:+d} ({}): {}",
                                                       offset, name, error);
                    return false;
                }
                steps.push_back(&motions.back());
            }
        }
    }
    return true;
}

void add_neighbour_frames(RegressionInputs& in, const std::vector<NeighbourFrame>& frames,
                          FirstPassFace image, FirstPassFace guide, FirstPassFace features,
                          const Plane& zero_offset)
{
    if (frames.empty())
        return;
    in.features.push_back(&zero_offset);
    for (const NeighbourFrame& f : frames) {
        RegressionFrame r;
        for (int c = 0; c < 3; ++c) {
            r.image[c] = face(f.color, image, c);
            r.guide[c] = face(f.color, guide, c);
            r.variance[c] = &f.color.variance[c];
        }
        for (const FeaturePlanes& p : f.features)
            r.features.push_back(face(p, features));
        r.features.push_back(&f.offset_feature);
        in.other_frames.push_back(std::move(r));
    }
}

}  // namespace mcdn
