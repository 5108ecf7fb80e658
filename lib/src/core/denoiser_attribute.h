// Which denoiser made a frame's colour. The denoiser ops set it on their output; sure's
// output is the denoiser's frame with SURE's channels added, so it carries it on; mix picks
// the mixing network trained for that denoiser by it (PD §5.3 trains one h_NN per
// denoiser: ours differ most where the KPCN op beats NFOR, models/README.md).
#pragma once

namespace mcdn {

constexpr const char* kDenoiserAttribute = "mcdn:denoiser";

}  // namespace mcdn
