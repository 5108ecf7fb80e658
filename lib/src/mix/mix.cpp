// Progressive mix (PD §4): alpha from a model, bounded by the t-test, z = x + alpha'(y - x).
#include "mcdn/mix.h"

#include "core/channels.h"
#include "core/op_prepare.h"
#include "mcdn/sure.h"
#include "mix/mix_steps.h"

namespace mcdn {

namespace {

// The channels sure wrote, by name; a missing one is an error that says to run --sure.
bool read_mix_inputs(MixInputs& in, const ImageBuf& src, const AovSet& aovs, std::string& error)
{
    const ImageSpec& spec = src.spec();
    for (int c = 0; c < 3; ++c) {
        in.y[c] = read_plane(src, aovs.channels(Role::Color)[c]);
        in.variance[c] = read_plane(src, aovs.channels(Role::ColorVariance)[c], true);
        const std::pair<Plane*, const char*> named[] = {
            { &in.x[c], sure_channels::kNoisy[c] },
            { &in.sure[c], sure_channels::kSure[c] },
            { &in.divergence[c], sure_channels::kDivergence[c] },
            { &in.residual[c], sure_channels::kResidual[c] },
        };
        for (const auto& [plane, name] : named) {
            int channel = spec.channelindex(name);
            if (channel < 0) {
                error = OIIO::Strutil::fmt::format(
                    "mix: channel '{}' not found: run sure first (mcdntool ... --nfor --sure --mix)",
                    name);
                return false;
            }
            *plane = read_plane(src, channel);
        }
    }
    return true;
}

}  // namespace

bool mix(ImageBuf& dst, const ImageBuf& src, const MixOptions& options, ROI roi, int nthreads)
{
    AovSet aovs;
    if (!prepare_op(dst, src, options.aovs, aovs, "mix"))
        return false;
    std::string error;
    MixInputs in;
    if (!aovs.require({ Role::Color, Role::ColorVariance }, src.spec(), error)
        || !read_mix_inputs(in, src, aovs, error)) {
        dst.errorfmt("{}", error);
        return false;
    }

    // mcdn/skip.h: tiles where z can only be x.
    const ConvergedTiles passed = tiles_mixing_to_x(in, options.skip);
    const Plane zero(in.x[0].width, in.x[0].height);
    Plane alpha[3];
    if (passed.all()) {
        for (int c = 0; c < 3; ++c)
            alpha[c] = zero;
    } else if (options.model == MixOptions::Model::Net) {
        nn::Net net;
        const std::string path = options.weights.empty() ? default_mix_weights() : options.weights;
        if (!load_mix_net(net, path, error)
            || !net_alpha(alpha, in, net, error, nullptr, network_regions(passed, net, 256))) {
            dst.errorfmt("{}", error);
            return false;
        }
        if (options.outlier_relative_variance > 0)
            for (int c = 0; c < 3; ++c)
                outlier_floor(alpha[c], in.variance[c], in.y[c], in.divergence[c],
                              in.residual[c], options.outlier_relative_variance);
    } else {
        analytic_alpha(alpha, in, options.analytic_radius);
    }

    if (options.t_test) {
        float sigma_s = t_test_sigma(in, options.t_sigma_scale);
        for (int c = 0; c < 3; ++c)
            t_test_bound(alpha[c], in.x[c], in.y[c], in.variance[c], sigma_s, options);
    }
    for (int c = 0; c < 3; ++c)
        pass_through_converged(alpha[c], zero, passed);

    // z = x + alpha' (y - x)
    ROI where = output_roi(src, roi);
    std::vector<int> alpha_channels;
    if (options.output_alpha)
        alpha_channels = add_channels(dst, { "mix.alpha.R", "mix.alpha.G", "mix.alpha.B" });
    for (int c = 0; c < 3; ++c) {
        Plane z(in.x[c].width, in.x[c].height);
        for (size_t i = 0; i < z.size(); ++i)
            z.px[i] = sanitize(in.x[c].px[i] + alpha[c].px[i] * (in.y[c].px[i] - in.x[c].px[i]));
        pass_through_converged(z, in.x[c], passed);
        write_plane(dst, aovs.channels(Role::Color)[c], z, where);
        if (options.output_alpha)
            write_plane(dst, alpha_channels[c], alpha[c], where);
    }
    // Extra AOVs that sure recorded x for: the same alpha', so they still add up to z.
    for (const AovSet::Extra& extra : aovs.extras()) {
        if (extra.channels.size() != 3)
            continue;
        for (int c = 0; c < 3; ++c) {
            const int noisy = src.spec().channelindex(sure_channels::noisy_extra(extra.names[c]));
            if (noisy < 0)
                break;
            Plane x = read_plane(src, noisy), y = read_plane(src, extra.channels[c]);
            for (size_t i = 0; i < x.size(); ++i)
                x.px[i] = sanitize(x.px[i] + alpha[c].px[i] * (y.px[i] - x.px[i]));
            write_plane(dst, extra.channels[c], x, where);
        }
    }
    return true;
}

ImageBuf mix(const ImageBuf& src, const MixOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    mix(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
