// `import mcdenoise` (its compiled part, mcdenoise._mcdenoise): the library's ops for Python
// pipeline steps. Every op takes and returns OpenImageIO.ImageBuf (the types of
// python3-openimageio's module, shared through pybind11),
// releases the GIL while it works, and raises RuntimeError with the library's message.
#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "mcdn/aov.h"
#include "mcdn/chain.h"
#include "mcdn/cnn.h"
#include "mcdn/denoise.h"
#include "mcdn/frames.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"
#include "mcdn/stages.h"
#include "mcdn/sure.h"

#include "module_steps.h"

namespace py = pybind11;
using OIIO::ImageBuf;

namespace {

using namespace mcdn_python;

// Read_inputs, write, validate: files in and out, and the checks mcdntool makes.
void bind_files(py::module_& m)
{
    m.def(
        "read_inputs",
        [](const std::vector<std::pair<std::string, std::string>>& files, const std::string& chain,
           const std::string& preset, const std::map<std::string, std::string>& aovs,
           const std::map<std::string, std::string>& settings) {
            std::vector<mcdn::InputFile> inputs;
            for (const auto& [path, kind] : files) {
                // 'seed' files one after another: one render's seeds (mcdn::combine_seeds).
                if (kind == "seed" && !inputs.empty() && !inputs.back().seeds.empty()) {
                    inputs.back().seeds.push_back(path);
                    continue;
                }
                auto k = mcdn::input_kind_from_name(kind == "seed" ? "mean" : kind);
                if (!k)
                    throw std::runtime_error(path + ": kind '" + kind
                                             + "' is not mean, variance, halfA, halfB or seed");
                inputs.push_back({ path, *k });
                if (kind == "seed")
                    inputs.back().seeds = { path };
            }
            // With a chain, of the variance and half files only what its stages read (as
            // mcdntool and the OIIO plugin read them); else every channel.
            mcdn::InputSelection selection;
            if (!chain.empty()) {
                std::vector<std::string> names;
                std::string error;
                if (!mcdn::parse_chain(names, chain, error))
                    throw std::runtime_error(error);
                selection =
                    mcdn::chain_input_selection(names, settings, mcdn::gives_variance(inputs));
                selection.aovs = aov_spec(preset, aovs, "");
            }
            ImageBuf merged;
            bool ok;
            {
                py::gil_scoped_release release;
                ok = mcdn::read_inputs(merged, inputs, selection);
            }
            if (!ok)
                throw std::runtime_error(merged.geterror());
            return merged;
        },
        py::arg("files"), py::arg("chain") = "", py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(),
        py::arg("settings") = std::map<std::string, std::string>(),
        "Read [(path, 'mean'|'variance'|'halfA'|'halfB'|'seed'), ...] into one ImageBuf "
        "(variance channels prefixed 'variance.', halves 'A.' and 'B.'). 'seed' files one "
        "after another are K renders of the frame with different seeds: read as their mean "
        "with its variance and, for an even K, halves. A directory path reads a Tungsten "
        "buffer set. chain: the stages that will run ('oidn,sure,mix', 'denoise', as "
        "run_chain takes them; with preset, aovs and settings as they will get them): of the "
        "variance and half files only the channels those stages read (a Blender frame's four "
        "files: 42 channels for 'oidn,sure,mix' rather than 70). Default: every channel.");

    m.def(
        "write",
        [](const ImageBuf& image, const std::string& path, const std::string& datatype,
           const std::vector<std::string>& channels, const std::string& compression) {
            if (!datatype.empty() && datatype != "half" && datatype != "float")
                throw std::runtime_error("write: datatype='" + datatype
                                         + "' is not half or float ('' keeps the input's)");
            mcdn::WriteOptions o;
            if (!datatype.empty())
                o.datatype = datatype == "half" ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT;
            o.channels = channels;
            o.compression = compression;
            std::string error;
            std::vector<std::string> warnings;
            bool ok;
            {
                py::gil_scoped_release release;
                ok = mcdn::write_image(image, path, o, error, &warnings);
            }
            if (!ok)
                throw std::runtime_error(error);
            // NaN/Inf written as they came in, values clamped for half (io.h).
            for (const auto& w : warnings)
                py::module_::import("warnings")
                    .attr("warn")(w, py::module_::import("builtins").attr("RuntimeWarning"));
        },
        py::arg("image"), py::arg("path"), py::arg("datatype") = "",
        py::arg("channels") = std::vector<std::string>(), py::arg("compression") = "",
        "Write through a temporary file renamed into place (never a partial file). Each channel "
        "keeps the type it had in the input and the file its compression unless datatype "
        "('half', 'float') or compression ('zip', 'dwaa:45', ...) says otherwise.");

    m.def(
        "validate",
        [](const ImageBuf& image, const std::string& preset,
           const std::map<std::string, std::string>& aovs) {
            mcdn::AovSet set;
            std::string error;
            if (!mcdn::resolve_aovs(set, aov_spec(preset, aovs, ""), image.spec(), error)
                || !set.require({ mcdn::Role::Color }, image.spec(), error)
                || !mcdn::validate_inputs(image, set, error))
                throw std::runtime_error(error);
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(),
        "Raise if the colour, halves or features hold NaN, Inf or huge values.");
}

// Prefilter, nfor and cnn, the denoisers.
void bind_denoisers(py::module_& m)
{
    m.def(
        "prefilter",
        [](const ImageBuf& src, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           int window, int patch, float k, bool skip, float converged, int nthreads) {
            auto o = stage_options<mcdn::PrefilterOptions>("prefilter",
                                                           aov_spec(preset, aovs, colorspace),
                                                           { { "window", text(window) },
                                                             { "patch", text(patch) },
                                                             { "k", text(k) },
                                                             { "skip", text(skip) },
                                                             { "converged", text(converged) } });
            return run(src, o.aovs, Halves::Read, [&](ImageBuf& d, const ImageBuf& s) {
                return mcdn::prefilter(d, s, o, {}, nthreads);
            });
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("window") = 11, py::arg("patch") = 7, py::arg("k") = 0.5f, py::arg("skip") = true,
        py::arg("converged") = mcdn::SkipOptions().max_relative_error, py::arg("nthreads") = 0,
        "NFOR feature prefilter (NFOR §5.1).");

    m.def(
        "nfor",
        [](const ImageBuf& src, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           int window, int patch, bool mse, bool selection, bool extras,
           const std::string& outliers, bool fallback, bool skip, float converged,
           const std::vector<ImageBuf*>& previous, const std::vector<ImageBuf*>& next,
           int nthreads) {
            auto o = stage_options<mcdn::NforOptions>("nfor", aov_spec(preset, aovs, colorspace),
                                                      { { "window", text(window) },
                                                        { "patch", text(patch) },
                                                        { "mse", text(mse) },
                                                        { "selection", text(selection) },
                                                        { "extras", text(extras) },
                                                        { "outliers", outliers },
                                                        { "fallback", text(fallback) },
                                                        { "skip", text(skip) },
                                                        { "converged", text(converged) } });
            const CheckedFrames checked_frames(previous, next, o.aovs, Halves::Read);
            o.previous_frames = checked_frames.previous;
            o.next_frames = checked_frames.next;
            return run(src, o.aovs, Halves::Read, [&](ImageBuf& d, const ImageBuf& s) {
                return mcdn::nfor(d, s, o, {}, nthreads);
            });
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("window") = 19, py::arg("patch") = 7, py::arg("mse") = false,
        py::arg("selection") = false, py::arg("extras") = true, py::arg("outliers") = "drop",
        py::arg("fallback") = mcdn::NforOptions().fallback, py::arg("skip") = true,
        py::arg("converged") = mcdn::SkipOptions().max_relative_error,
        py::arg("previous") = std::vector<ImageBuf*>(), py::arg("next") = std::vector<ImageBuf*>(),
        py::arg("nthreads") = 0,
        "NFOR: first-order regression denoiser (NFOR §5.2-5.4). extras: denoise the extra "
        "AOVs (light groups) with the beauty's weights. outliers: a pixel holding one sample "
        "worth a hundred of its neighbours is kept out of the regressions and removed "
        "('drop'), put back ('keep') or left in ('off'). fallback: the safety net, a 32x32 "
        "tile where NFOR's own MSE estimate is above the render's variance is the render. skip: "
        "pass converged tiles (worst "
        "relative standard error <= converged) through and drop constant features. previous, "
        "next: cross-frame (NFOR §8), the neighbouring frames of the shot, nearest first "
        "(at most 4 each), aligned to this one by the motion vectors (Blender's Vector "
        "pass, RenderMan's forward and backward, or aovs={'motion': 'X,Y,Z,W'}).");

    m.def(
        "cnn",
        [](const ImageBuf& src, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           const std::string& weights, bool extras, const std::string& outliers, bool skip,
           float converged, const std::vector<ImageBuf*>& previous,
           const std::vector<ImageBuf*>& next, int nthreads) {
            auto o = stage_options<mcdn::CnnOptions>("cnn", aov_spec(preset, aovs, colorspace),
                                                     { { "weights", weights },
                                                       { "extras", text(extras) },
                                                       { "outliers", outliers },
                                                       { "skip", text(skip) },
                                                       { "converged", text(converged) } });
            mcdn::CombineFramesOptions frames;
            frames.aovs = o.aovs;
            const CheckedFrames checked_frames(previous, next, o.aovs, Halves::WithoutVariance);
            frames.previous_frames = checked_frames.previous;
            frames.next_frames = checked_frames.next;
            return run(src, o.aovs, Halves::WithoutVariance, [&](ImageBuf& d, const ImageBuf& s) {
                if (previous.empty() && next.empty())
                    return mcdn::cnn(d, s, o, {}, nthreads);
                return mcdn::denoise_with_frames(
                    d, s, frames,
                    [&](ImageBuf& dd, const ImageBuf& ss) {
                        return mcdn::cnn(dd, ss, o, {}, nthreads);
                    },
                    nthreads);
            });
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("weights") = "", py::arg("extras") = true, py::arg("outliers") = "drop",
        py::arg("skip") = true, py::arg("converged") = mcdn::SkipOptions().max_relative_error,
        py::arg("previous") = std::vector<ImageBuf*>(), py::arg("next") = std::vector<ImageBuf*>(),
        py::arg("nthreads") = 0,
        "KPCN: kernel-predicting CNN denoiser with our trained weights. extras: denoise the "
        "extra AOVs (light groups) with the beauty's kernels. outliers: a pixel holding one "
        "sample worth a hundred of its neighbours is taken out of the network's input and "
        "removed ('drop', as nfor's rule) or left in ('off'). previous, next: cross-frame, "
        "the neighbouring frames of the shot (nearest first, at most 4 each), aligned by "
        "the motion vectors and combined with this one where they agree before the "
        "network (mcdn/frames.h; without a colour variance or halves, as Cycles writes, "
        "weighed by how well the frames agree with each other); the result keeps this "
        "frame's own variance and halves.");
    m.def("release_cnn_workers", &mcdn::release_cnn_workers,
          "Frees the networks and buffers cnn() keeps for its next call (~350 MB per thread).");
}

// Sure and mix: the error estimate of any denoiser and the progressive mix (PD).
void bind_progressive(py::module_& m)
{
    m.def(
        "sure",
        [](const ImageBuf& src, py::object denoiser, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           int probes, float eps, bool fallback, bool skip, float converged, int nthreads) {
            auto o = stage_options<mcdn::SureOptions>("sure", aov_spec(preset, aovs, colorspace),
                                                      { { "probes", text(probes) },
                                                        { "eps", text(eps) },
                                                        { "fallback", text(fallback) },
                                                        { "skip", text(skip) },
                                                        { "converged", text(converged) } });
            mcdn::Denoiser f;
            // NFOR reads the halves; a callable may (without a variance, the stages do).
            bool reads_halves = false;
            if (py::isinstance<py::str>(denoiser))
                f = named_denoiser(denoiser.cast<std::string>(), o.aovs, o.skip, nthreads,
                                   o.denoiser_radius, reads_halves);
            else {
                // A Python callable ImageBuf -> ImageBuf; called with the GIL held.
                auto callable = denoiser.cast<py::function>();
                f = [callable](ImageBuf& dst, const ImageBuf& in) {
                    py::gil_scoped_acquire acquire;
                    try {
                        dst = callable(in).cast<ImageBuf>();
                        return true;
                    } catch (const std::exception& e) {
                        dst.errorfmt("python denoiser: {}", e.what());
                        return false;
                    }
                };
            }
            return run(src, o.aovs, reads_halves ? Halves::Read : Halves::WithoutVariance,
                       [&](ImageBuf& d, const ImageBuf& s) {
                           return mcdn::sure(d, s, f, o, {}, nthreads);
                       });
        },
        py::arg("image"), py::arg("denoiser") = "nfor", py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("probes") = 1, py::arg("eps") = 1e-3f,
        py::arg("fallback") = mcdn::SureOptions().fallback, py::arg("skip") = true,
        py::arg("converged") = mcdn::SkipOptions().max_relative_error, py::arg("nthreads") = 0,
        "Monte-Carlo SURE (PD §3.2) of a denoiser: 'nfor', 'cnn', 'prefilter,nfor' or a "
        "callable ImageBuf -> ImageBuf. Returns the denoised image with noisy.*, sure.*, "
        "sure.divergence.*, "
        "sure.residual.* channels. fallback: 32x32 tiles where SURE finds the denoiser worse "
        "than the render are the render (the safety net; False keeps the denoiser's).");

    m.def(
        "mix",
        [](const ImageBuf& src, const std::string& model, const std::string& weights, bool t_test,
           bool alpha, const std::string& preset, const std::map<std::string, std::string>& aovs,
           const std::string& colorspace, bool skip, float converged, int nthreads) {
            auto o = stage_options<mcdn::MixOptions>("mix", aov_spec(preset, aovs, colorspace),
                                                     { { "model", model },
                                                       { "weights", weights },
                                                       { "ttest", text(t_test) },
                                                       { "alpha", text(alpha) },
                                                       { "skip", text(skip) },
                                                       { "converged", text(converged) } });
            return run(src, o.aovs, Halves::Never, [&](ImageBuf& d, const ImageBuf& s) {
                return mcdn::mix(d, s, o, {}, nthreads);
            });
        },
        py::arg("image"), py::arg("model") = "net", py::arg("weights") = "",
        py::arg("t_test") = true, py::arg("alpha") = false, py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("skip") = true, py::arg("converged") = mcdn::SkipOptions().max_relative_error,
        py::arg("nthreads") = 0,
        "Progressive mix (PD §4) of the output of sure(): z = x + alpha'(y - x). With "
        "model='net' (the default; 'analytic': eq. 9) and no weights: the network trained for the "
        "denoiser named in the "
        "image's 'mcdn:denoiser' attribute (set by nfor and cnn; models/mix_cnn.mcdnw for "
        "'cnn', else models/mix.mcdnw).");
}

// Denoise, plan and run_chain: the best chain the inputs allow, or any chain of the stage
// table (mcdn/stages.h) by name.
void bind_chains(py::module_& m)
{
    m.def(
        "run_chain",
        [](const ImageBuf& src, const std::string& chain, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           const std::map<std::string, std::string>& settings, py::object progress, int nthreads) {
            mcdn::ChainOptions o;
            std::string error;
            if (!mcdn::parse_chain(o.stages, chain, error))
                throw std::runtime_error(error);
            o.aovs = aov_spec(preset, aovs, colorspace);
            o.settings = settings;
            const PythonProgress reporter(progress);
            o.progress = reporter.callback();
            bool halves = false;  // a stage that reads them (NFOR, its prefilter)
            for (const std::string& name : o.stages)
                halves |=
                    mcdn::find_stage(name)->reads_halves(mcdn::stage_settings(settings, name));
            return reporter.run_with([&] {
                return run(src, o.aovs, halves ? Halves::Read : Halves::WithoutVariance,
                           [&](ImageBuf& d, const ImageBuf& s) {
                               return mcdn::run_chain(d, s, o, {}, nthreads);
                           });
            });
        },
        py::arg("image"), py::arg("chain"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("settings") = std::map<std::string, std::string>(),
        py::arg("progress") = py::none(), py::arg("nthreads") = 0,
        "Stages by name, as a recipe or mcdntool runs them: 'oidn,sure,mix', "
        "'prefilter,nfor', 'cnn', ... (mcdntool --help lists them). settings: "
        "{'oidn.weights': '/path/to/oidn-weights', 'sure.probes': '2', ...}, the stages' keys. "
        "progress: as denoise()'s.");

    m.def(
        "denoise",
        [](const ImageBuf& src, const std::string& preset,
           const std::map<std::string, std::string>& aovs, const std::string& colorspace,
           const std::map<std::string, std::string>& settings, py::object progress, int nthreads) {
            mcdn::DenoiseOptions o;
            o.aovs = aov_spec(preset, aovs, colorspace);
            o.settings = settings;
            const PythonProgress reporter(progress);
            o.progress = reporter.callback();
            return reporter.run_with([&] {
                return run(src, o.aovs, Halves::WithoutVariance,
                           [&](ImageBuf& d, const ImageBuf& s) {
                               return mcdn::denoise(d, s, o, {}, nthreads);
                           });
            });
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(), py::arg("colorspace") = "",
        py::arg("settings") = std::map<std::string, std::string>(),
        py::arg("progress") = py::none(), py::arg("nthreads") = 0,
        "The best chain the inputs allow: with a colour variance cnn, sure and mix (the "
        "network), without one cnn alone (plan() says which and why). settings: "
        "{'cnn.tile': '256', 'mix.ttest': '0', ...}, the stages' keys. progress: called as "
        "progress(stage, fraction) while the stages run, fraction of the whole run and never "
        "decreasing; returning True or raising cancels (the exception is raised here).");
    m.def(
        "plan",
        [](const ImageBuf& src, const std::string& preset,
           const std::map<std::string, std::string>& aovs) {
            mcdn::DenoisePlan plan;
            std::string error;
            if (!mcdn::plan_denoise(plan, src.spec(), aov_spec(preset, aovs, ""), error))
                throw std::runtime_error(error);
            return plan.describe();
        },
        py::arg("image"), py::arg("preset") = "",
        py::arg("aovs") = std::map<std::string, std::string>(),
        "One line: the chain denoise() runs on this image, and why.");
}

// Metrics against a reference, per frame and between frames.
void bind_metrics(py::module_& m)
{
    m.def(
        "metrics",
        [](const ImageBuf& image, const ImageBuf& reference, std::vector<int> channels,
           std::vector<int> reference_channels, bool trim, const ImageBuf* reference_variance) {
            mcdn::MetricsOptions o;
            o.image_channels = channels;
            o.reference_channels = reference_channels.empty() ? channels : reference_channels;
            o.trim = trim;
            mcdn::Metrics r;
            mcdn::ReferenceNoise noise;
            std::string error;
            bool ok;
            {
                py::gil_scoped_release release;
                ok = mcdn::compute_metrics(r, image, reference, o, error)
                     && (!reference_variance
                         || mcdn::compute_reference_noise(noise, reference, *reference_variance, o,
                                                          error));
            }
            if (!ok)
                throw std::runtime_error(error);
            std::map<std::string, double> out { { "mse", r.mse },       { "rmse", r.rmse },
                                                { "relmse", r.relmse }, { "smape", r.smape },
                                                { "psnr", r.psnr },     { "ssim", r.ssim } };
            if (reference_variance) {
                out["mse_reference_noise"] = noise.mse;
                out["relmse_reference_noise"] = noise.relmse;
            }
            return out;
        },
        py::arg("image"), py::arg("reference"), py::arg("channels") = std::vector<int> { 0, 1, 2 },
        py::arg("reference_channels") = std::vector<int>(), py::arg("trim") = false,
        py::arg("reference_variance") = nullptr,
        "MSE, RMSE, relMSE, SMAPE, PSNR, SSIM as a dict; with the reference's variance of the "
        "mean (laid out as the reference), also mse_reference_noise and "
        "relmse_reference_noise: what the reference's own noise adds to mse and relmse "
        "(mcdn/metrics.h ReferenceNoise).");

    m.def(
        "temporal_metrics",
        [](const ImageBuf& image, const ImageBuf& previous, const ImageBuf& reference,
           const ImageBuf& previous_reference, const ImageBuf* motion, std::vector<int> channels,
           std::vector<int> reference_channels, std::vector<int> motion_channels,
           std::pair<double, double> motion_scale, bool trim, const ImageBuf* reference_variance,
           const ImageBuf* previous_reference_variance) {
            mcdn::TemporalOptions o;
            o.metrics.image_channels = channels;
            o.metrics.reference_channels =
                reference_channels.empty() ? channels : reference_channels;
            o.metrics.trim = trim;
            if (motion_channels.size() != 2)
                throw std::runtime_error("temporal_metrics: motion_channels needs 2 (x, y)");
            o.motion_x = motion_channels[0];
            o.motion_y = motion_channels[1];
            o.motion_scale_x = motion_scale.first;
            o.motion_scale_y = motion_scale.second;
            if (bool(reference_variance) != bool(previous_reference_variance))
                throw std::runtime_error("temporal_metrics: give both references' variances "
                                         "or neither");
            mcdn::TemporalMetrics r;
            mcdn::ReferenceNoise noise;
            std::string error;
            bool ok;
            {
                py::gil_scoped_release release;
                ok = mcdn::compute_temporal_metrics(r, image, previous, reference,
                                                    previous_reference, motion, o, error)
                     && (!reference_variance
                         || mcdn::compute_temporal_reference_noise(
                             noise, reference, *reference_variance, *previous_reference_variance,
                             motion, o, error));
            }
            if (!ok)
                throw std::runtime_error(error);
            std::map<std::string, double> out { { "mse", r.mse },
                                                { "relmse", r.relmse },
                                                { "pixels", double(r.pixels) } };
            if (reference_variance) {
                out["mse_reference_noise"] = noise.mse;
                out["relmse_reference_noise"] = noise.relmse;
            }
            return out;
        },
        py::arg("image"), py::arg("previous"), py::arg("reference"), py::arg("previous_reference"),
        py::arg("motion") = nullptr, py::arg("channels") = std::vector<int> { 0, 1, 2 },
        py::arg("reference_channels") = std::vector<int>(),
        py::arg("motion_channels") = std::vector<int> { 0, 1 },
        py::arg("motion_scale") = std::pair<double, double>(1.0, 1.0), py::arg("trim") = false,
        py::arg("reference_variance") = nullptr, py::arg("previous_reference_variance") = nullptr,
        "Flicker of frame `image` after `previous` against their references (mcdn/metrics.h): "
        "temporal MSE and relMSE of the frame-to-frame difference after warping the previous "
        "frame by `motion` (pixel p was at p + motion_scale * motion[p] before, per axis, +y "
        "down; Cycles' Vector X, Y: motion_scale=(1, -1); None: still). With both "
        "references' variances of the mean (laid out as `reference`), also "
        "mse_reference_noise and relmse_reference_noise: what their own noise adds.");
}

}  // namespace

PYBIND11_MODULE(_mcdenoise, m)
{
    m.doc() = "mcdenoise: Monte Carlo render denoisers on OpenImageIO.ImageBuf";
    py::module_::import("OpenImageIO");  // registers ImageBuf with pybind11
    m.attr("__version__") = mcdn::version();
    bind_files(m);
    bind_denoisers(m);
    bind_progressive(m);
    bind_chains(m);
    bind_metrics(m);
}
