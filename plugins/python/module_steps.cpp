// The Python module's shared steps (module_steps.h).
#include "module_steps.h"

#include <OpenImageIO/strutil.h>

#include "mcdn/chain.h"
#include "mcdn/io.h"
#include "mcdn/stages.h"
#include "mcdn/sure.h"

namespace mcdn_python {

// The AOV spec from the keyword arguments every op shares.
mcdn::AovSpec aov_spec(const std::string& preset, const std::map<std::string, std::string>& aovs,
                       const std::string& colorspace)
{
    mcdn::AovSpec spec;
    spec.preset = preset;
    spec.colorspace = colorspace;
    std::string error;
    for (const auto& [role, channels] : aovs)
        if (!spec.parse_override(role + "=" + channels, error))
            throw std::runtime_error(error);
    return spec;
}

std::string text(int value)
{
    return std::to_string(value);
}
std::string text(bool value)
{
    return value ? "1" : "0";
}
std::string text(float value)
{
    return OIIO::Strutil::fmt::format("{}", value);
}

// What mcdntool and the plugin check of their inputs before any stage, for an image a
// Python step hands an op: its values (mcdn::validate_inputs: NaN, Inf, huge values, a
// negative variance, a normal that is no direction, in any channel a stage reads) and the
// half buffers the op reads (mcdn::check_halves). A RuntimeError names the file and
// channel; tiles whose halves were repaired are a RuntimeWarning. Returns the image to run
// on: `src`, or `repaired` (a copy) where halves were repaired. An AOV set that does not
// resolve is left to the op to report.
const ImageBuf& checked(const ImageBuf& src, const mcdn::AovSpec& spec, ImageBuf& repaired,
                        Halves halves)
{
    mcdn::AovSet set;
    std::string error;
    if (!mcdn::resolve_aovs(set, spec, src.spec(), error))
        return src;
    const bool local = src.localpixels() && src.spec().format == OIIO::TypeDesc::FLOAT;
    ImageBuf copy;
    if (!local && !copy.copy(src, OIIO::TypeDesc::FLOAT))
        throw std::runtime_error(copy.geterror());
    const ImageBuf& values = local ? src : copy;
    const bool reads_halves =
        set.has(mcdn::Role::ColorA) && set.has(mcdn::Role::ColorB)
        && (halves == Halves::Read
            || (halves == Halves::WithoutVariance && !set.has(mcdn::Role::ColorVariance)));
    std::vector<std::pair<int, int>> tiles;
    {
        py::gil_scoped_release release;
        if (mcdn::validate_inputs(values, set, error) && reads_halves) {
            if (local)
                copy.copy(src);
            mcdn::check_halves(copy, set, tiles, error);
        }
    }
    if (!error.empty())
        throw std::runtime_error(error);
    if (tiles.empty())
        return src;
    py::module_::import("warnings")
        .attr("warn")(std::to_string(tiles.size())
                          + " tile(s) of 32x32 pixels: the half buffers disagree with the "
                            "render there (a corrupt block?); their halves are the render's colour",
                      py::module_::import("builtins").attr("RuntimeWarning"));
    repaired = std::move(copy);
    return repaired;
}

CheckedFrames::CheckedFrames(const std::vector<ImageBuf*>& before,
                             const std::vector<ImageBuf*>& after, const mcdn::AovSpec& spec,
                             Halves halves)
{
    repaired.reserve(before.size() + after.size());
    for (auto [from, to] : { std::pair { &before, &previous }, std::pair { &after, &next } })
        for (ImageBuf* frame : *from) {
            repaired.emplace_back();
            to->push_back(&checked(*frame, spec, repaired.back(), halves));
        }
}

// Denoisers by name ("nfor", "cnn", "prefilter,nfor": Denoisers of the stage table,
// mcdn/stages.h) as one, with how far they reach (SureOptions::denoiser_radius) and whether
// one of them reads the half buffers.
mcdn::Denoiser named_denoiser(const std::string& chain, const mcdn::AovSpec& spec,
                              const mcdn::SkipOptions& skip, int nthreads, int& radius,
                              bool& reads_halves)
{
    std::vector<std::string> names;
    std::string error;
    const std::vector<std::string> known = mcdn::stage_names({ mcdn::StageKind::Denoiser });
    auto unknown = [&]() {
        return std::runtime_error("sure: unknown denoiser '" + chain + "' (use "
                                  + OIIO::Strutil::join(known, ", ")
                                  + ", several joined by commas, or a callable)");
    };
    if (!mcdn::parse_chain(names, chain, error))
        throw unknown();
    mcdn::StageContext context;
    context.aovs = spec;
    context.nthreads = nthreads;
    const mcdn::Settings settings = { { "skip", text(skip.enabled) },
                                      { "converged", text(skip.max_relative_error) } };
    std::vector<std::pair<std::string, mcdn::Denoiser>> denoisers;
    std::vector<mcdn::StageReach> reach;
    reads_halves = false;
    for (const std::string& name : names) {
        const mcdn::StageInfo& stage = *mcdn::find_stage(name);
        mcdn::MadeStage made;
        if (stage.kind != mcdn::StageKind::Denoiser)
            throw unknown();
        if (!stage.make(made, settings, context, error))
            throw std::runtime_error("sure: " + name + ": " + error);
        denoisers.emplace_back(name, std::move(made.run));
        reach.push_back(made.reach);
        reads_halves |= stage.reads_halves(settings);
    }
    radius = mcdn::chain_radius(reach);
    return mcdn::compose(std::move(denoisers));
}

PythonProgress::PythonProgress(py::object progress) : m_progress(std::move(progress)) { }

mcdn::ProgressCallback PythonProgress::callback() const
{
    if (m_progress.is_none())
        return {};
    // The stages never call it twice at once (mcdn/progress.h).
    return [progress = m_progress, raised = m_raised](const std::string& stage, float fraction) {
        py::gil_scoped_acquire gil;
        try {
            return py::bool_(progress(stage, fraction)).cast<bool>();
        } catch (py::error_already_set&) {
            *raised = std::current_exception();
            return true;
        }
    };
}

}  // namespace mcdn_python
