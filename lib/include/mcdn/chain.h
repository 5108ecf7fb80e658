// A chain of stages by name, e.g. "prefilter,nfor,sure,mix", for front ends that take a
// recipe rather than commands (the oiiotool format plugin, Python's run_chain). Denoisers
// before "sure" form the denoiser SURE estimates the error of; "mix" needs "sure" first.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"

namespace mcdn {

struct ChainOptions {
    AovSpec aovs;
    /// Stage names in order: prefilter, nfor, cnn, sure, mix; or "denoise" alone, the best
    /// chain the inputs allow (mcdn/denoise.h).
    std::vector<std::string> stages = { "denoise" };
    /// Per-stage settings "stage.key" -> value: nfor.window=19, sure.probes=4,
    /// mix.model=net, mix.ttest=0, ... (the same keys as mcdntool's modifiers).
    std::map<std::string, std::string> settings;
    /// Given to every stage (mcdn/progress.h).
    ProgressCallback progress;
};

/// Parses "prefilter,nfor,sure,mix" (or "denoise") and checks the order; false with `error`
/// on an unknown stage or a mix without a sure before it.
bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error);

/// The feature channels (albedo, normal, depth, visibility: every face) of a resolved set:
/// what a chain with a prefilter puts back into its output from its input unless a stage
/// asked for features-out.
std::vector<std::string> feature_channel_names(const AovSet& aovs, const ImageSpec& spec);
/// Copies the named channels of `input` into the same-named channels of dst; false with
/// `error` when either lacks one.
bool copy_channels_by_name(ImageBuf& dst, const ImageBuf& input,
                           const std::vector<std::string>& names, std::string& error);

/// Runs the chain on src (a merged buffer, io.h). dst as the last stage leaves it, except
/// that a prefilter's features are replaced by src's own unless prefilter.features-out or
/// nfor.features-out is set.
bool run_chain(ImageBuf& dst, const ImageBuf& src, const ChainOptions& options, ROI roi = {},
               int nthreads = 0);

}  // namespace mcdn
