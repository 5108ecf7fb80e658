// alpha' of the progressive mix (PD §4) on one band's inputs: the model's alpha (eq. 9 or
// the network, §4.3), bounded by the t-test (eq. 12-18), 0 where z can only be x.
#include <algorithm>

#include "core/trace.h"
#include "mix/mix_steps.h"
#include "nn/network_regions.h"

namespace mcdn {

bool mix_alpha(Plane alpha[3], ConvergedTiles& passed, const MixInputs& in,
               const MixOptions& options, nn::Net* net, float sigma_s, std::string& error)
{
    StageTrace trace("mix");
    // mcdn/skip.h: tiles where z can only be x.
    passed = tiles_mixing_to_x(in, options.skip);
    trace.mark("band: tiles mixing to x");
    const Plane zero(in.x[0].width, in.x[0].height);
    if (passed.all()) {  // nothing to mix on the band: no model, no t-test
        for (int c = 0; c < 3; ++c)
            alpha[c] = zero;
        return true;
    }
    if (net) {
        if (!net_alpha(alpha, in, *net, error, nullptr, network_regions(passed, *net, 256)))
            return false;
        trace.mark("band: network alpha (4.3)");
        if (options.analytic_floor) {
            // The network's alpha is at least the analytic model's (MixOptions::analytic_floor).
            Plane analytic[3];
            analytic_alpha(analytic, in, options.analytic_radius);
            for (int c = 0; c < 3; ++c)
                for (size_t i = 0; i < alpha[c].size(); ++i)
                    alpha[c].px[i] = std::max(alpha[c].px[i], analytic[c].px[i]);
            trace.mark("band: analytic floor (eq. 9)");
        }
    } else {
        analytic_alpha(alpha, in, options.analytic_radius);
    }
    // Either model: a render pixel that is an outlier of its own variance leans to y
    // (outlier_floor.cpp; the box averages of eq. 9 spread a firefly's terms over 441
    // pixels as the network's saturated inputs hide them).
    for (int c = 0; c < 3; ++c)
        outlier_floor(alpha[c], in.variance[c], in.y[c], in.divergence[c], in.residual[c],
                      options.outlier_relative_variance, options.drop_relative_variance);
    trace.mark("band: outlier floor");

    if (options.t_test)
        for (int c = 0; c < 3; ++c)
            t_test_bound(alpha[c], in.x[c], in.y[c], in.variance[c], sigma_s, options);
    trace.mark("band: t-test (4.2)");
    for (int c = 0; c < 3; ++c)
        pass_through_converged(alpha[c], zero, passed);
    return true;
}

}  // namespace mcdn
