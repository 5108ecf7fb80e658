// A chain of stages by name, e.g. "prefilter,nfor,sure,mix", for front ends that take a
// recipe rather than commands (the oiiotool format plugin, Python's run_chain). Denoisers
// before "sure" form the denoiser SURE estimates the error of; "mix" needs "sure" first.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"

namespace mcdn {

struct ChainOptions {
    AovSpec aovs;
    /// Stage names in order: prefilter, nfor, cnn, sure, mix.
    std::vector<std::string> stages = { "prefilter", "nfor" };
    /// Per-stage settings "stage.key" -> value: nfor.window=19, sure.probes=4,
    /// mix.model=net, mix.ttest=0, ... (the same keys as mcdntool's modifiers).
    std::map<std::string, std::string> settings;
};

/// Parses "prefilter,nfor,sure,mix" and checks the order; false with `error` on an unknown
/// stage or a mix without a sure before it.
bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error);

/// Runs the chain on src (a merged buffer, io.h). dst as the last stage leaves it.
bool run_chain(ImageBuf& dst, const ImageBuf& src, const ChainOptions& options, ROI roi = {},
               int nthreads = 0);

}  // namespace mcdn
