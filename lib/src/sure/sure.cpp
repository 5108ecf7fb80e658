// Monte-Carlo SURE of a denoiser (PD §2.3 eq. 1, §3.2 eq. 2). Reads top to bottom:
// denoise once, choose the probe step, probe K times, assemble SURE per pixel and channel.
#include "mcdn/sure.h"

#include <array>
#include <cmath>

#include "core/channels.h"
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

    // Eq. 2: probe with b ~ N(0, Sigma); the render and both halves move together. The
    // probes run before y = F(x) and keep only their colour, so at most three full frames
    // (render, probed render, response) are alive at once.
    const double eps = probe_step(p, options.epsilon_relative);
    const int w = p.x[0].width, h = p.x[0].height;
    auto probe = [&](int k, int c) {
        Plane b(w, h);
        for (size_t i = 0; i < b.size(); ++i)
            b.px[i] = std::sqrt(p.variance[c].px[i]) * standard_normal(options.seed, uint64_t(k), i * 3 + c);
        return b;
    };
    std::vector<int> moved = color;
    for (Role half : { Role::ColorA, Role::ColorB })
        if (aovs.has(half))
            moved.insert(moved.end(), aovs.channels(half).begin(), aovs.channels(half).end());
    const int probes = eps > 0 ? options.probes : 0;
    std::vector<std::array<Plane, 3>> responses(probes);  // F(x + eps b_k), colour only
    for (int k = 0; k < probes; ++k) {
        Plane b[3] = { probe(k, 0), probe(k, 1), probe(k, 2) };
        ImageBuf probed = noisy.copy(OIIO::TypeDesc::FLOAT);
        probed.specmod().attribute(sure_channels::kProbeAttribute, 1);
        for (size_t g = 0; g < moved.size(); g += 3)
            add_probe(probed, { moved[g], moved[g + 1], moved[g + 2] }, b, eps);
        ImageBuf response;
        if (!denoiser(response, probed)) {
            dst.errorfmt("sure: the denoiser failed on probe {}: {}", k, response.geterror());
            return false;
        }
        for (int c = 0; c < 3; ++c)
            responses[k][c] = read_plane(response, color[c]);
    }

    // y = F(x): the result we report SURE for.
    ImageBuf denoised;
    if (!denoiser(denoised, noisy)) {
        dst.errorfmt("sure: the denoiser failed: {}", denoised.geterror());
        return false;
    }
    Plane y[3];
    for (int c = 0; c < 3; ++c)
        y[c] = read_plane(denoised, color[c]);
    Plane divergence[3] = { Plane(w, h), Plane(w, h), Plane(w, h) };
    for (int k = 0; k < probes; ++k)
        for (int c = 0; c < 3; ++c) {
            Plane b = probe(k, c);
            const Plane& f = responses[k][c];
            for (size_t i = 0; i < f.size(); ++i)
                divergence[c].px[i] += float(b.px[i] * (double(f.px[i]) - y[c].px[i])
                                             / (eps * options.probes));
            responses[k][c] = Plane();
        }

    // Eq. 1 per pixel and channel (d = 1): SURE = (y - x)^2 + 2 sigma^2 f'(x) - sigma^2.
    dst = std::move(denoised);
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
