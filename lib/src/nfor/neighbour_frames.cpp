#include "nfor/neighbour_frames.h"

#include "ops/motion.h"

namespace mcdn {

namespace {

/// Far from any colour: a patch that reaches a pixel outside the aligned frame gets
/// distance kDistanceClamp there, and weight 0.
constexpr float kOutsideGuide = 1e10f;

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
        // Guides (the halves cross-guide, the mean guides itself on the one-buffer path) are
        // far off outside; the halves path reads no mean of a neighbour.
        f.color.variance[c] = warp(f.color.variance[c], a, 0.0f);
        if (halves) {
            f.color.mean[c] = Plane();
            f.color.half_a[c] = warp(f.color.half_a[c], a, kOutsideGuide);
            f.color.half_b[c] = warp(f.color.half_b[c], a, kOutsideGuide);
        } else {
            f.color.mean[c] = warp(f.color.mean[c], a, kOutsideGuide);
        }
    }
    for (FeaturePlanes& p : f.features) {
        p.mean = warp(p.mean, a, 0.0f);
        p.half_a = warp(p.half_a, a, 0.0f);
        p.half_b = warp(p.half_b, a, 0.0f);
    }
    f.offset_feature = Plane(a.width, a.height, float(f.offset));
}

const Plane* face(const ColorPlanes& c, Face f, int channel)
{
    return f == Face::HalfA   ? &c.half_a[channel]
           : f == Face::HalfB ? &c.half_b[channel]
                              : &c.mean[channel];
}

const Plane* face(const FeaturePlanes& p, Face f)
{
    return f == Face::HalfA ? &p.half_a : f == Face::HalfB ? &p.half_b : &p.mean;
}

}  // namespace

bool read_neighbour_frames(std::vector<NeighbourFrame>& frames, const ImageBuf& src,
                           const std::vector<const ImageBuf*>& previous,
                           const std::vector<const ImageBuf*>& next,
                           const NeighbourReading& reading, int nthreads, std::string& error)
{
    std::vector<AlignedFrame> aligned;
    const std::vector<Role> required =
        reading.halves ? std::vector<Role> { Role::Color, Role::ColorA, Role::ColorB }
                       : std::vector<Role> { Role::Color, Role::ColorVariance };
    if (!align_neighbours(aligned, src, *reading.aovs, *reading.spec, previous, next, required,
                          error))
        return false;
    for (const AlignedFrame& a : aligned) {
        std::vector<FeatureChannel> features;
        std::string missing;
        if (!features_in(features, *reading.features, src.spec(), a.frame->spec(), missing)) {
            error = a.error("no channel " + missing);
            return false;
        }
        NeighbourFrame f;
        f.offset = a.offset;
        read_frame(f, *a.frame, a.aovs, features, reading, nthreads);
        align(f, a.alignment, reading.halves);
        frames.push_back(std::move(f));
    }
    return true;
}

void add_neighbour_frames(RegressionInputs& in, const std::vector<NeighbourFrame>& frames,
                          Face image, Face guide, Face features, const Plane& zero_offset)
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
