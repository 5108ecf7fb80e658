// How far a chain of denoisers reaches (mcdn/settings.h): SURE runs a large frame in bands
// with this halo (SureOptions::denoiser_radius), so it must cover the whole chain.
#include "mcdn/settings.h"

#include "mcdn/cnn.h"

namespace mcdn {

StageReach stage_reach(const PrefilterOptions& options)
{
    const int r = receptive_radius(options);
    return { r, r, true };
}

StageReach stage_reach(const NforOptions& options)
{
    // nfor keeps its input's "mcdn:prefiltered" and prefilters itself only without it.
    return { receptive_radius(options, false), receptive_radius(options, true), false };
}

StageReach stage_reach(const CnnOptions& options)
{
    const int r = receptive_radius(options);  // -1: the weights cannot be read
    return { r, r, false };
}

int chain_radius(const std::vector<StageReach>& stages)
{
    int total = 0;
    bool prefiltered = false;
    for (const StageReach& stage : stages) {
        const int r = prefiltered ? stage.prefiltered_radius : stage.radius;
        if (r < 0)
            return -1;
        total += r;
        prefiltered |= stage.prefilters;
    }
    return total;
}

}  // namespace mcdn
