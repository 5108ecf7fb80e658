// Progressive mix (PD §4): alpha from a model, bounded by the t-test, z = x + alpha'(y - x).
// Everything but the t-test's sigma_s is local (alpha reaches the model's neighbourhood and
// the t-test's 11x11 around a pixel), so a large frame runs in bands of
// MixOptions::band_pixels with that reach as halo, sigma_s fixed on the whole frame first:
// memory follows the band, the result is the whole frame's.
#include "mcdn/mix.h"

#include <OpenImageIO/strutil.h>

#include "ops/bands.h"
#include "core/channels.h"
#include "core/frame_facts.h"
#include "core/attributes.h"
#include "core/op_prepare.h"
#include "core/progress.h"
#include "core/trace.h"
#include "mcdn/sure.h"
#include "mix/mix_steps.h"

namespace mcdn {

namespace {

// Where the planes of MixInputs are in src: the colour role holds y; sure wrote the rest.
struct MixChannels {
    int y[3], variance[3], x[3], sure[3], divergence[3], residual[3];
};

std::string needs_sure(const char* missing)
{
    return OIIO::Strutil::fmt::format(
        "mix mixes the render with a denoiser by the error --sure estimates: run --sure "
        "before it (--cnn --sure --mix, or --denoise); the input has no '{}'",
        missing);
}

// The channels sure wrote, by name; a missing one is an error that says to run --sure.
bool find_mix_channels(MixChannels& ch, const ImageSpec& spec, const AovSet& aovs,
                       std::string& error)
{
    for (int c = 0; c < 3; ++c) {
        ch.y[c] = aovs.channels(Role::Color)[c];
        ch.variance[c] = aovs.channels(Role::ColorVariance)[c];
        const std::pair<int*, const char*> named[] = {
            { &ch.x[c], sure_channels::kNoisy[c] },
            { &ch.sure[c], sure_channels::kSure[c] },
            { &ch.divergence[c], sure_channels::kDivergence[c] },
            { &ch.residual[c], sure_channels::kResidual[c] },
        };
        for (const auto& [channel, name] : named) {
            *channel = spec.channelindex(name);
            if (*channel < 0) {
                error = needs_sure(name);
                return false;
            }
        }
    }
    return true;
}

MixInputs read_mix_inputs(const ImageBuf& src, const MixChannels& ch, const ROI& rows, int nthreads)
{
    MixInputs in;
    const int* channels[6] = { ch.y, ch.variance, ch.x, ch.sure, ch.divergence, ch.residual };
    Plane* groups[6] = { in.y, in.variance, in.x, in.sure, in.divergence, in.residual };
    std::vector<PlaneRead> reads;
    for (int g = 0; g < 6; ++g)
        for (int c = 0; c < 3; ++c)
            reads.push_back({ channels[g][c], &groups[g][c], g == 1 });
    read_planes(src, reads, rows, nthreads);
    return in;
}

// How far alpha' at a pixel reaches into the inputs: the model's neighbourhood, then the
// t-test's (it reads the neighbours' alpha).
int mix_radius(const MixOptions& o, const nn::Net* net)
{
    return (net ? net->receptive_radius() : o.analytic_radius) + (o.t_test ? o.t_radius : 0);
}

}  // namespace

bool mix(ImageBuf& dst, const ImageBuf& src, const MixOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "mix"))
        return false;
    StageTrace trace("mix");
    AovSet aovs;
    if (!prepare_op(dst, src, options.aovs, aovs, "mix", nthreads))
        return false;
    trace.mark("copy src to dst");
    std::string error;
    MixChannels channels;
    // Without --sure before it, that is the fix to name (not a missing channel of its own).
    if (src.spec().channelindex(sure_channels::kSure[0]) < 0) {
        dst.errorfmt("{}", needs_sure(sure_channels::kSure[0]));
        return false;
    }
    if (!aovs.require({ Role::Color, Role::ColorVariance }, src.spec(), error)
        || !find_mix_channels(channels, src.spec(), aovs, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    // Fixed on the whole frame before the bands.
    const float sigma_s = t_test_sigma(src, channels.x, options.t_sigma_scale);
    nn::Net net;
    const bool use_net = options.model == MixOptions::Model::Net;
    if (use_net) {
        const std::string path =
            options.weights.empty()
                ? default_mix_weights(src.spec().get_string_attribute(kDenoiserAttribute))
                : options.weights;
        if (!load_mix_net(net, path, error)) {
            dst.errorfmt("{}", error);
            return false;
        }
    }

    const ROI where = output_roi(src, roi);
    const int radius = mix_radius(options, use_net ? &net : nullptr);
    const std::vector<Band> bands =
        plan_bands(src.roi(), radius, is_frame_band(src.spec()) ? 0 : options.band_pixels);
    // In place, one band reads all it needs before it writes; a band's halo would read rows
    // the band above has written.
    if (&dst == &src && bands.size() > 1) {
        const ImageBuf input = src.copy(OIIO::TypeDesc::FLOAT);
        return mix(dst, input, options, roi, nthreads);
    }
    std::vector<int> alpha_channels;
    if (options.output_alpha)
        alpha_channels = add_channels(dst, { "mix.alpha.R", "mix.alpha.G", "mix.alpha.B" });
    ProgressCounter progress(options.progress, "mix", int(bands.size()));
    for (const Band& band : bands) {
        const MixInputs in = read_mix_inputs(src, channels, band.cut, nthreads);
        Plane alpha[3];
        ConvergedTiles passed;
        if (!mix_alpha(alpha, passed, in, options, use_net ? &net : nullptr, sigma_s, error)) {
            dst.errorfmt("{}", error);
            return false;
        }
        trace.mark("band: alpha (4.1-4.3)");
        // z = x + alpha' (y - x) on the band's own rows.
        ROI own = where;
        own.ybegin = std::max(where.ybegin, band.own_begin);
        own.yend = std::min(where.yend, band.own_end);
        const int band_y = band.cut.ybegin;
        // On a band where y = x throughout (mix_alpha ran neither model nor t-test), z is x.
        const bool all_x = passed.all();
        Plane z[3];
        std::vector<int> out_channels;
        std::vector<const Plane*> out_planes;
        for (int c = 0; c < 3; ++c) {
            if (!all_x) {
                z[c] = Plane(in.x[c].width, in.x[c].height);
                for (size_t i = 0; i < z[c].size(); ++i)
                    z[c].px[i] =
                        sanitize(in.x[c].px[i] + alpha[c].px[i] * (in.y[c].px[i] - in.x[c].px[i]));
                pass_through_converged(z[c], in.x[c], passed);
            }
            out_channels.push_back(channels.y[c]);
            out_planes.push_back(all_x ? &in.x[c] : &z[c]);
            if (options.output_alpha) {
                out_channels.push_back(alpha_channels[c]);
                out_planes.push_back(&alpha[c]);
            }
        }
        write_rows(dst, out_channels, out_planes, band_y, own);
        // Extra AOVs that sure recorded x for: the same alpha', so they still add up to z.
        for (const AovSet::Extra& extra : aovs.extras()) {
            if (extra.channels.size() != 3)
                continue;
            for (int c = 0; c < 3; ++c) {
                const int noisy =
                    src.spec().channelindex(sure_channels::noisy_extra(extra.names[c]));
                if (noisy < 0)
                    break;
                Plane x = read_rows(src, noisy, band.cut),
                      y = read_rows(src, extra.channels[c], band.cut);
                for (size_t i = 0; i < x.size(); ++i)
                    x.px[i] = sanitize(x.px[i] + alpha[c].px[i] * (y.px[i] - x.px[i]));
                write_rows(dst, extra.channels[c], x, band_y, own);
            }
        }
        trace.mark("band: z = x + alpha (y - x)");
        if (!progress.advance()) {
            dst.errorfmt("{}", progress.error());
            return false;
        }
    }
    return true;
}

int receptive_radius(const MixOptions& options, const std::string& denoiser)
{
    if (options.model != MixOptions::Model::Net)
        return mix_radius(options, nullptr);
    nn::Net net;
    std::string error;
    const std::string path =
        options.weights.empty() ? default_mix_weights(denoiser) : options.weights;
    return load_mix_net(net, path, error) ? mix_radius(options, &net) : -1;
}

ImageBuf mix(const ImageBuf& src, const MixOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    mix(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
