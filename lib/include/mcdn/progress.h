// Progress of long stages: an optional callback in each stage's Options (and in
// DenoiseOptions, ChainOptions), called with the stage's name and the fraction done so far,
// from any of the stage's threads (never two calls at once, fractions never decreasing
// within one call of the op). mcdntool prints it as a line on a terminal (-v); Python's
// denoise(progress=f) calls f(stage, fraction).
#pragma once

#include <functional>
#include <string>

namespace mcdn {

using ProgressCallback = std::function<void(const std::string& stage, float fraction)>;

}  // namespace mcdn
