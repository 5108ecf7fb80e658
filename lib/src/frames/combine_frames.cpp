// mcdn::combine_frames (mcdn/frames.h): the neighbours aligned (ops/motion.h), one NL-means
// weight per neighbour and pixel from the colour's patches, then every noisy light channel
// averaged over the frames with those weights.
#include "mcdn/frames.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "ops/color_planes.h"
#include "ops/motion.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "mcdn/color.h"
#include "nl_means/nl_means.h"

namespace mcdn {

bool frames_have_measured_variance(const AovSet& aovs)
{
    return aovs.has(Role::ColorVariance) || (aovs.has(Role::ColorA) && aovs.has(Role::ColorB));
}

namespace {

// E[min of the 4 squared differences to a pixel's neighbours] = 0.387 sigma^2 for
// independent Gaussian noise of variance sigma^2 (measured: 4M pixels); its inverse.
constexpr float kLeastSquaredDifferenceToVariance = 2.58f;

/// The colour and the variance of its mean of one frame (the role's, else from the halves);
/// without either, the mean alone (the variance is estimated_variance's).
bool read_color(ColorPlanes& out, const ImageBuf& frame, const AovSet& aovs, bool measured,
                std::string& error)
{
    if (measured != frames_have_measured_variance(aovs)) {
        error = measured ? "no colour variance or half buffers, which this frame has"
                         : "a colour variance or half buffers, which this frame has not";
        return false;
    }
    if (measured) {
        read_color_planes(out, frame, aovs, !aovs.has(Role::ColorVariance));
        return true;
    }
    std::vector<PlaneRead> reads;
    for (int c = 0; c < 3; ++c)
        reads.push_back({ aovs.channels(Role::Color)[c], &out.mean[c] });
    read_planes(frame, reads);
    return true;
}

/// Mean of each pixel's (2F+1)² patch, clipped to the plane (rows of prefix sums, then
/// columns; in double, so that no running rounding is left).
Plane box_mean(const Plane& in, int F, int nthreads)
{
    const int w = in.width, h = in.height;
    Plane across(w, h), out(w, h);
    parallel_for_index(h, nthreads, [&](int y) {
        std::vector<double> prefix(size_t(w) + 1, 0.0);
        const float* row = in.row(y);
        for (int x = 0; x < w; ++x)
            prefix[size_t(x) + 1] = prefix[size_t(x)] + row[x];
        float* o = across.row(y);
        for (int x = 0; x < w; ++x) {
            const int x0 = std::max(0, x - F), x1 = std::min(w, x + F + 1);
            o[x] = float((prefix[size_t(x1)] - prefix[size_t(x0)]) / (x1 - x0));
        }
    });
    parallel_for_index(w, nthreads, [&](int x) {
        std::vector<double> prefix(size_t(h) + 1, 0.0);
        for (int y = 0; y < h; ++y)
            prefix[size_t(y) + 1] = prefix[size_t(y)] + across(x, y);
        for (int y = 0; y < h; ++y) {
            const int y0 = std::max(0, y - F), y1 = std::min(h, y + F + 1);
            out(x, y) = float((prefix[size_t(y1)] - prefix[size_t(y0)]) / (y1 - y0));
        }
    });
    return out;
}

/// Without a measured variance (Cycles writes none): each pixel's colour variance, per
/// channel, the smaller of two bounds, each a patch mean: the least squared difference to
/// its four neighbours, scaled to the variance of independent noise (the variance where the
/// picture is flat or an edge runs through it, more across fine texture; a mean over the
/// directions counted an edge's step as noise, and the frames then ghosted the edge: on our
/// Blender sequence 0.0043 against 0.0036), and half the squared difference to the aligned
/// frame that agrees best (the variance where some frame shows the same, more where none
/// does).
/// A frame rendered with the same seed (Blender's default: Seed's animate off) agrees too
/// well where nothing moves: it gets full weight there and brings no samples, as it would
/// with a variance.
bool estimate_variance(ColorPlanes& own, const std::vector<AlignedFrame>& aligned,
                       const CombineFramesOptions& o, int nthreads, std::string& error)
{
    const int w = own.mean[0].width, h = own.mean[0].height, F = o.patch_radius;
    for (int c = 0; c < 3; ++c) {
        const Plane& mine = own.mean[c];
        Plane across(w, h);
        parallel_for_index(h, nthreads, [&](int y) {
            for (int x = 0; x < w; ++x) {
                float least = std::numeric_limits<float>::max();
                for (const auto& [nx, ny] :
                     { std::pair<int, int>(x - 1, y), { x + 1, y }, { x, y - 1 }, { x, y + 1 } })
                    if (nx >= 0 && nx < w && ny >= 0 && ny < h) {
                        const float d = mine(x, y) - mine(nx, ny);
                        least = std::min(least, d * d);
                    }
                across(x, y) = least < std::numeric_limits<float>::max()
                                   ? kLeastSquaredDifferenceToVariance * least
                                   : 0.0f;
            }
        });
        own.variance[c] = box_mean(across, F, nthreads);
    }
    for (const AlignedFrame& a : aligned) {
        ColorPlanes other;
        if (!read_color(other, *a.frame, a.aovs, false, error)) {
            error = a.error(error);
            return false;
        }
        Plane outside(w, h);
        for (size_t i = 0; i < outside.size(); ++i)
            outside.px[i] = a.alignment.source[i] < 0 ? 1.0f : 0.0f;
        const Plane reaches_out = box_mean(outside, F, nthreads);
        for (int c = 0; c < 3; ++c) {
            const Plane v = warp(other.mean[c], a.alignment, 0.0f);
            Plane half_sq(w, h);
            for (size_t i = 0; i < half_sq.size(); ++i) {
                const float d = outside.px[i] > 0.0f ? 0.0f : own.mean[c].px[i] - v.px[i];
                half_sq.px[i] = 0.5f * d * d;
            }
            const Plane agreement = box_mean(half_sq, F, nthreads);
            Plane& bound = own.variance[c];
            for (size_t i = 0; i < bound.size(); ++i)
                if (reaches_out.px[i] == 0.0f)
                    bound.px[i] = std::min(bound.px[i], agreement.px[i]);
        }
    }
    for (Plane& bound : own.variance)
        for (float& v : bound.px)
            v = sanitize_variance(v);
    return true;
}

/// The weight of the aligned neighbour at each pixel: exp(-max(0, d²)), d² the largest
/// channel's patch mean of NFOR's per-pixel distance (nl_means.h), +clamp where the
/// alignment leaves the neighbour, so that no patch reaching there gets weight.
Plane frame_weight(const ColorPlanes& own, const ColorPlanes& other,
                   const FrameAlignment& alignment, const CombineFramesOptions& o, int nthreads)
{
    const int w = own.mean[0].width, h = own.mean[0].height;
    const float k2 = o.k * o.k;
    Plane distance(w, h);
    for (int c = 0; c < 3; ++c) {
        const Plane v = warp(other.mean[c], alignment, 0.0f);
        // Without a measured variance the other frame's is taken as this one's (the same
        // render settings).
        const bool measured = other.variance[c].size() > 0;
        const Plane vv = measured ? warp(other.variance[c], alignment, 0.0f) : Plane();
        Plane term(w, h);
        parallel_for_index(h, nthreads, [&](int y) {
            for (int x = 0; x < w; ++x) {
                const size_t i = size_t(y) * w + x;
                if (alignment.source[i] < 0) {
                    term.px[i] = nlm::kDistanceClamp;
                    continue;
                }
                const float vp = own.variance[c].px[i], vq = measured ? vv.px[i] : vp;
                const float diff = own.mean[c].px[i] - v.px[i];
                const float d =
                    (diff * diff - (vp + std::min(vp, vq))) / (nlm::kEpsilon + k2 * (vp + vq));
                term.px[i] = std::min(d, nlm::kDistanceClamp);
            }
        });
        const Plane patch = box_mean(term, o.patch_radius, nthreads);
        for (size_t i = 0; i < distance.size(); ++i)
            distance.px[i] = c == 0 ? patch.px[i] : std::max(distance.px[i], patch.px[i]);
    }
    Plane weight(w, h);
    for (size_t i = 0; i < weight.size(); ++i)
        weight.px[i] = std::exp(-std::max(0.0f, distance.px[i]));
    return weight;
}

/// The channels combined: the light (colour, its halves, Blender's light passes, the
/// diffuse/specular components, extra AOVs) and, in `variances`, their variances.
void light_channels(const AovSet& aovs, const ImageSpec& spec, std::set<int>& means,
                    std::set<int>& variances)
{
    for (Role r : { Role::Color, Role::ColorA, Role::ColorB, Role::Diffuse, Role::Specular,
                    Role::DiffuseDirect, Role::DiffuseIndirect, Role::GlossyDirect,
                    Role::GlossyIndirect, Role::Emission, Role::Environment })
        for (int c : aovs.channels(r))
            means.insert(c);
    for (int c : aovs.channels(Role::ColorVariance))
        variances.insert(c);
    for (const AovSet::Extra& e : aovs.extras()) {
        for (const std::vector<int>* list : { &e.channels, &e.half_a, &e.half_b })
            for (int c : *list)
                means.insert(c);
        for (int c : e.variance)
            variances.insert(c);
    }
    // The faces of the light passes that the inputs hold by name (Cycles' variance file
    // and halves carry every pass).
    for (int c : std::set<int>(means)) {
        const std::string& name = spec.channelnames[size_t(c)];
        for (InputKind k : { InputKind::Variance, InputKind::HalfA, InputKind::HalfB }) {
            const int face = spec.channelindex(input_kind_prefix(k) + name);
            if (face >= 0)
                (k == InputKind::Variance ? variances : means).insert(face);
        }
    }
    for (int c : variances)
        means.erase(c);
}

bool combine_in_working_space(ImageBuf& dst, const ImageBuf& src, const CombineFramesOptions& o,
                              ROI roi, int nthreads)
{
    const char* op = "frames";
    AovSet aovs;
    std::string error;
    ColorPlanes own;
    if (!resolve_aovs(aovs, o.aovs, src.spec(), error)
        || !aovs.require({ Role::Color, Role::Motion }, src.spec(), error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    const bool measured = frames_have_measured_variance(aovs);
    if (!read_color(own, src, aovs, measured, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    std::vector<AlignedFrame> aligned;
    if (!align_neighbours(aligned, src, aovs, o.aovs, o.previous_frames, o.next_frames,
                          { Role::Color }, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    if (!measured && !estimate_variance(own, aligned, o, nthreads, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    std::vector<Plane> weights;
    for (const AlignedFrame& a : aligned) {
        ColorPlanes other;
        if (!read_color(other, *a.frame, a.aovs, measured, error)) {
            dst.errorfmt("{}: {}", op, a.error(error));
            return false;
        }
        weights.push_back(frame_weight(own, other, a.alignment, o, nthreads));
    }
    own = ColorPlanes();
    // Each pixel's total weight: its own 1 and the neighbours'.
    Plane total(src.spec().width, src.spec().height, 1.0f);
    for (const Plane& wk : weights)
        for (size_t i = 0; i < total.size(); ++i)
            total.px[i] += wk.px[i];
    std::set<int> means, variances;
    light_channels(aovs, src.spec(), means, variances);
    // Every channel is found in every neighbour before anything is written.
    std::vector<std::vector<int>> index(aligned.size());
    for (size_t k = 0; k < aligned.size(); ++k)
        for (const std::set<int>* set : { &means, &variances })
            for (int c : *set) {
                const std::string& name = src.spec().channelnames[size_t(c)];
                index[k].push_back(aligned[k].frame->spec().channelindex(name));
                if (index[k].back() < 0) {
                    dst.errorfmt("{}: {}", op, aligned[k].error("no channel " + name));
                    return false;
                }
            }
    AovSet dst_aovs;
    if (!prepare_op(dst, src, o.aovs, dst_aovs, op, nthreads))
        return false;
    roi = output_roi(dst, roi);
    size_t n = 0;
    for (const std::set<int>* set : { &means, &variances }) {
        const bool variance = set == &variances;
        for (int c : *set) {
            // Each channel is read from src before it is written (dst may be src).
            const Plane mine = read_plane(src, c, variance);
            Plane sum = mine;
            for (size_t k = 0; k < aligned.size(); ++k) {
                const Plane other = warp(read_plane(*aligned[k].frame, index[k][n], variance),
                                         aligned[k].alignment, 0.0f);
                const Plane& wk = weights[k];
                for (size_t i = 0; i < sum.size(); ++i)
                    sum.px[i] += (variance ? wk.px[i] * wk.px[i] : wk.px[i]) * other.px[i];
            }
            for (size_t i = 0; i < sum.size(); ++i) {
                const float t = variance ? total.px[i] * total.px[i] : total.px[i];
                const float v = sum.px[i] / t;
                sum.px[i] = std::isfinite(v) ? v : mine.px[i];
            }
            write_plane(dst, c, sum, roi);
            ++n;
        }
    }
    return true;
}

}  // namespace

bool combine_frames(ImageBuf& dst, const ImageBuf& src, const CombineFramesOptions& options,
                    ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "frames"))
        return false;
    if (options.patch_radius < 0 || !(options.k > 0)) {
        dst.errorfmt("frames: patch must be >= 0 and k > 0 (patch {}, k {})", options.patch_radius,
                     options.k);
        return false;
    }
    return run_in_working_space(dst, src, options.aovs, "frames",
                                [&](ImageBuf& d, const ImageBuf& s) {
                                    return combine_in_working_space(d, s, options, roi, nthreads);
                                });
}

bool denoise_with_frames(ImageBuf& dst, const ImageBuf& src, const CombineFramesOptions& options,
                         const std::function<bool(ImageBuf&, const ImageBuf&)>& denoiser,
                         int nthreads)
{
    ImageBuf combined, denoised;
    if (!combine_frames(combined, src, options, {}, nthreads)) {
        dst.errorfmt("{}", combined.geterror());
        return false;
    }
    if (!denoiser(denoised, combined)) {
        dst.errorfmt("{}", denoised.geterror());
        return false;
    }
    combined.reset();
    AovSet aovs;
    std::string error;
    if (!resolve_aovs(aovs, options.aovs, src.spec(), error)) {
        dst.errorfmt("frames: {}", error);
        return false;
    }
    std::set<int> means, variances, written;
    light_channels(aovs, src.spec(), means, variances);
    for (int c : aovs.channels(Role::Color))
        written.insert(c);
    for (const AovSet::Extra& e : aovs.extras())
        written.insert(e.channels.begin(), e.channels.end());
    for (const std::set<int>* set : { &means, &variances })
        for (int c : *set) {
            if (written.count(c))
                continue;
            const int to = denoised.spec().channelindex(src.spec().channelnames[size_t(c)]);
            if (to >= 0)
                write_plane(denoised, to, read_plane(src, c, set == &variances), denoised.roi());
        }
    dst = std::move(denoised);
    return true;
}

ImageBuf combine_frames(const ImageBuf& src, const CombineFramesOptions& options, ROI roi,
                        int nthreads)
{
    ImageBuf dst;
    combine_frames(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
