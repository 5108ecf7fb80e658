// Monte-Carlo SURE of a denoiser (PD §2.3 eq. 1, §3.2 eq. 2). Reads top to bottom:
// denoise once, choose the probe step, probe K times, assemble SURE per pixel and channel.
#include "mcdn/sure.h"

#include <cmath>

#include "core/channels.h"
#include "core/converged_tiles.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/random.h"
#include "mcdn/color.h"

namespace mcdn {

namespace {

struct ColourPlanes {
    Plane x[3], variance[3];
};

// eps such that RMS(eps * b) = epsilon_relative * mean|x|  (see SureOptions).
double probe_step(const ColourPlanes& p, float epsilon_relative)
{
    double sum_abs = 0, sum_var = 0;
    size_t n = 0;
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < p.x[c].size(); ++i) {
            sum_abs += std::fabs(p.x[c].px[i]);
            sum_var += p.variance[c].px[i];
            ++n;
        }
    if (n == 0 || sum_var <= 0 || sum_abs <= 0)
        return 0;  // nothing to probe: no noise, or a black image
    return epsilon_relative * (sum_abs / n) / std::sqrt(sum_var / n);
}

// Adds eps*b to the given channels of `buf` (b is one probe, one plane per colour channel).
void add_probe(ImageBuf& buf, const std::vector<int>& channels, const Plane probe[3],
               double eps)
{
    for (int c = 0; c < 3; ++c) {
        Plane plane = read_plane(buf, channels[c]);
        for (size_t i = 0; i < plane.size(); ++i)
            plane.px[i] += float(eps * probe[c].px[i]);
        write_plane(buf, channels[c], plane, buf.roi());
    }
}

}  // namespace

namespace {

bool sure_in_working_space(ImageBuf& dst, const ImageBuf& src, const Denoiser& denoiser,
                           const SureOptions& options, ROI roi, int nthreads)
{
    AovSet aovs;
    ImageBuf noisy;
    if (!prepare_op(noisy, src, options.aovs, aovs, "sure"))
        return dst.errorfmt("{}", noisy.geterror()), false;
    std::string error;
    if (!aovs.require({ Role::Color, Role::ColorVariance }, src.spec(), error)) {
        dst.errorfmt("sure: {}", error);
        return false;
    }
    if (!denoiser || options.probes < 1) {
        dst.errorfmt("sure: needs a denoiser and at least one probe (probes={})", options.probes);
        return false;
    }
    const auto& color = aovs.channels(Role::Color);
    ColourPlanes p;
    for (int c = 0; c < 3; ++c) {
        p.x[c] = read_plane(noisy, color[c]);
        p.variance[c] = read_plane(noisy, aovs.channels(Role::ColorVariance)[c], true);
    }

    // mcdn/skip.h: the denoiser's runs all skip the tiles of this map.
    const ConvergedTiles converged = converged_tiles_of(noisy, p.x, p.variance, options.skip);
    if (options.skip.enabled)
        noisy.specmod().attribute(kConvergedAttribute, encode_converged_tiles(converged));

    // y = F(x): the result we report SURE for.
    ImageBuf denoised;
    if (!denoiser(denoised, noisy)) {
        dst.errorfmt("sure: the denoiser failed: {}", denoised.geterror());
        return false;
    }
    Plane y[3];
    for (int c = 0; c < 3; ++c)
        y[c] = read_plane(denoised, color[c]);
    // Of those, the tiles the denoiser did pass through (a callable may not skip): no probes.
    const ConvergedTiles passed = tiles_where_equal(y, p.x, &converged);
    const Plane no_probe(noisy.spec().width, noisy.spec().height);

    // Eq. 2: probe with b ~ N(0, Sigma); the render and both halves move together.
    const double eps = probe_step(p, options.epsilon_relative);
    const int w = p.x[0].width, h = p.x[0].height;
    Plane divergence[3] = { Plane(w, h), Plane(w, h), Plane(w, h) };
    std::vector<int> moved = color;
    for (Role half : { Role::ColorA, Role::ColorB })
        if (aovs.has(half))
            moved.insert(moved.end(), aovs.channels(half).begin(), aovs.channels(half).end());
    // The moved channels' exact bits (read_plane would sanitize), restored after each probe.
    std::vector<std::vector<float>> unprobed(moved.size());
    auto channel_roi = [&](int channel) {
        ROI r = noisy.roi();
        r.chbegin = channel;
        r.chend = channel + 1;
        return r;
    };
    if (eps > 0)
        for (size_t m = 0; m < moved.size(); ++m) {
            unprobed[m].resize(size_t(noisy.spec().width) * noisy.spec().height);
            noisy.get_pixels(channel_roi(moved[m]), OIIO::TypeDesc::FLOAT, unprobed[m].data());
        }
    for (int k = 0; eps > 0 && k < options.probes; ++k) {
        Plane b[3];
        for (int c = 0; c < 3; ++c) {
            b[c] = Plane(w, h);
            for (size_t i = 0; i < b[c].size(); ++i)
                b[c].px[i] = std::sqrt(p.variance[c].px[i])
                             * standard_normal(options.seed, uint64_t(k), i * 3 + c);
            pass_through_converged(b[c], no_probe, passed);
        }
        // Probed in place and restored after (a copy of every channel per probe cost as
        // much as the denoiser's own work on half-converged frames).
        ImageBuf& probed = noisy;
        probed.specmod().attribute(sure_channels::kProbeAttribute, 1);
        for (size_t g = 0; g < moved.size(); g += 3)
            add_probe(probed, { moved[g], moved[g + 1], moved[g + 2] }, b, eps);
        ImageBuf response;
        const bool probe_ok = denoiser(response, probed);
        for (size_t m = 0; m < moved.size(); ++m)
            noisy.set_pixels(channel_roi(moved[m]), OIIO::TypeDesc::FLOAT, unprobed[m].data());
        noisy.specmod().erase_attribute(sure_channels::kProbeAttribute);
        if (!probe_ok) {
            dst.errorfmt("sure: the denoiser failed on probe {}: {}", k, response.geterror());
            return false;
        }
        for (int c = 0; c < 3; ++c) {
            Plane f = read_plane(response, color[c]);
            for (size_t i = 0; i < f.size(); ++i)
                divergence[c].px[i] += float(b[c].px[i] * (double(f.px[i]) - y[c].px[i])
                                             / (eps * options.probes));
        }
    }

    // Eq. 1 per pixel and channel (d = 1): SURE = (y - x)^2 + 2 sigma^2 f'(x) - sigma^2.
    dst = std::move(denoised);
    dst.specmod().erase_attribute(kConvergedAttribute);
    for (int c = 0; c < 3; ++c)  // the pass-through's f'(x) = 1
        pass_through_converged(divergence[c], p.variance[c], passed);
    std::vector<std::string> names;
    for (const auto* group : { sure_channels::kNoisy, sure_channels::kSure,
                               sure_channels::kDivergence, sure_channels::kResidual })
        names.insert(names.end(), group, group + 3);
    const size_t first_extra = names.size();
    std::vector<int> extra_channels;  // x of the extras, so that mix can mix them too
    for (const AovSet::Extra& extra : aovs.extras())
        if (extra.channels.size() == 3)
            for (int c = 0; c < 3; ++c) {
                names.push_back(sure_channels::noisy_extra(extra.names[c]));
                extra_channels.push_back(extra.channels[c]);
            }
    std::vector<int> out = add_channels(dst, names);
    ROI where = output_roi(src, roi);
    for (size_t e = 0; e < extra_channels.size(); ++e)
        write_plane(dst, out[first_extra + e], read_plane(noisy, extra_channels[e]), where);
    for (int c = 0; c < 3; ++c) {
        Plane residual(w, h), estimate(w, h);
        for (size_t i = 0; i < residual.size(); ++i) {
            double d = double(y[c].px[i]) - p.x[c].px[i];
            residual.px[i] = sanitize(float(d * d));
            divergence[c].px[i] = sanitize(divergence[c].px[i]);
            estimate.px[i] = sanitize(residual.px[i] + 2 * divergence[c].px[i] - p.variance[c].px[i]);
        }
        write_plane(dst, out[c], p.x[c], where);
        write_plane(dst, out[3 + c], estimate, where);
        write_plane(dst, out[6 + c], divergence[c], where);
        write_plane(dst, out[9 + c], residual, where);
    }
    return true;
}

}  // namespace

bool sure(ImageBuf& dst, const ImageBuf& src, const Denoiser& denoiser,
          const SureOptions& options, ROI roi, int nthreads)
{
    return run_in_working_space(dst, src, options.aovs, "sure", [&](ImageBuf& d, const ImageBuf& s) {
        return sure_in_working_space(d, s, denoiser, options, roi, nthreads);
    });
}

ImageBuf sure(const ImageBuf& src, const Denoiser& denoiser, const SureOptions& options,
              ROI roi, int nthreads)
{
    ImageBuf dst;
    sure(dst, src, denoiser, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
