// Progress of long stages: an optional callback in each stage's Options (and in
// DenoiseOptions, ChainOptions), called with the stage's name and the fraction done so far,
// from any of the stage's threads (never two calls at once, fractions never decreasing
// within one call of the op; a chain's fraction is of the whole chain). It returns true to
// cancel, as OIIO's ProgressCallback does: the op stops at its next tile or band and fails
// with "<stage>: cancelled by the progress callback". mcdntool prints it as a line (-v);
// Python's denoise(progress=f) calls f(stage, fraction), and an exception f raises cancels.
#pragma once

#include <functional>
#include <string>

namespace mcdn {

using ProgressCallback = std::function<bool(const std::string& stage, float fraction)>;

}  // namespace mcdn
