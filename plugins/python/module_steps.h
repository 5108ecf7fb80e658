// What every binding of the Python module shares (mcdenoise_module.cpp): the AOV spec and a
// stage's Options from keyword arguments, the checks mcdntool makes of its inputs, an op run
// without the GIL, named denoisers and progress callbacks.
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <pybind11/pybind11.h>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/settings.h"
#include "mcdn/skip.h"

namespace mcdn_python {

namespace py = pybind11;
using OIIO::ImageBuf;

/// The AOV spec from the keyword arguments every op shares.
mcdn::AovSpec aov_spec(const std::string& preset, const std::map<std::string, std::string>& aovs,
                       const std::string& colorspace);

/// A stage's Options from its keyword arguments, through the library's settings parser, so
/// Python checks values exactly as mcdntool and the recipe do ("nfor: window=4 must be ...").
template <class Options>
Options stage_options(const std::string& stage, const mcdn::AovSpec& aovs,
                      const mcdn::Settings& settings)
{
    Options o;
    o.aovs = aovs;
    std::string error;
    if (!mcdn::apply_settings(o, settings, error))
        throw std::runtime_error(stage + ": " + error);
    return o;
}

/// A keyword argument as a setting's text.
std::string text(int value);
std::string text(bool value);
std::string text(float value);

/// Which half buffers an op reads, as mcdntool decides what to read (its InputSelection):
/// NFOR's always, the other stages' only where there is no colour variance (they take the
/// halves' difference then), a stage's result's never (its colour is denoised).
enum class Halves { Read, WithoutVariance, Never };

/// What mcdntool and the plugin check of their inputs before any stage, for an image a
/// Python step hands an op: its values (mcdn::validate_inputs) and the half buffers the op
/// reads (mcdn::check_halves). A RuntimeError names the file and channel; tiles whose halves
/// were repaired are a RuntimeWarning. Returns `src`, or `repaired` (a copy) where halves
/// were repaired. An AOV set that does not resolve is left to the op to report.
const ImageBuf& checked(const ImageBuf& src, const mcdn::AovSpec& spec, ImageBuf& repaired,
                        Halves halves);

/// Runs an op in OIIO's shape on `src` as checked() passes it, without the GIL; its error
/// becomes a RuntimeError.
template <class Op>
ImageBuf run(const ImageBuf& src, const mcdn::AovSpec& spec, Halves halves, Op op)
{
    ImageBuf repaired;
    const ImageBuf& in = checked(src, spec, repaired, halves);
    ImageBuf dst;
    bool ok;
    {
        py::gil_scoped_release release;
        ok = op(dst, in);
    }
    if (!ok)
        throw std::runtime_error(dst.geterror());
    return dst;
}

/// checked() of the neighbouring frames of a cross-frame op, held with any repaired copies.
struct CheckedFrames {
    std::vector<ImageBuf> repaired;  // reserved up front: the pointers point into it
    std::vector<const ImageBuf*> previous, next;

    CheckedFrames(const std::vector<ImageBuf*>& before, const std::vector<ImageBuf*>& after,
                  const mcdn::AovSpec& spec, Halves halves);
};

/// Denoisers by name ("nfor", "cnn", "prefilter,nfor": Denoisers of the stage table,
/// mcdn/stages.h) as one, with how far they reach (SureOptions::denoiser_radius) and whether
/// one of them reads the half buffers.
mcdn::Denoiser named_denoiser(const std::string& chain, const mcdn::AovSpec& spec,
                              const mcdn::SkipOptions& skip, int nthreads, int& radius,
                              bool& reads_halves);

/// A Python progress(stage, fraction) as the stages' callback (none: none). It cancels the
/// run by returning True or by raising; run_with() then raises that exception (else the
/// op's RuntimeError, "cancelled by the progress callback").
class PythonProgress {
public:
    explicit PythonProgress(py::object progress);
    mcdn::ProgressCallback callback() const;
    /// op() under run(), the callback's exception raised in its place where there was one.
    template <class Call> ImageBuf run_with(Call call) const
    {
        try {
            return call();
        } catch (const std::runtime_error&) {
            if (*m_raised)
                std::rethrow_exception(*m_raised);
            throw;
        }
    }

private:
    py::object m_progress;
    std::shared_ptr<std::exception_ptr> m_raised = std::make_shared<std::exception_ptr>();
};

}  // namespace mcdn_python
