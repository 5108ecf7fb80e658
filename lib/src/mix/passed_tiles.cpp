// The tiles the progressive mix leaves to the render (MixOptions::skip, mcdn/skip.h).
#include "mix/mix_steps.h"

namespace mcdn {

ConvergedTiles tiles_mixing_to_x(const MixInputs& in, const SkipOptions& skip)
{
    // Not the converged map itself: where a denoiser did filter a converged tile (a callable
    // that does not skip), the mix still weighs its result.
    return skip.enabled ? tiles_where_equal(in.x, in.y) : ConvergedTiles();
}

}  // namespace mcdn
