#include "nfor/mse_estimate.h"

namespace mcdn {

std::vector<Plane> estimate_mse(const Plane* const half_a[3], const Plane* const half_b[3],
                                const Plane* const variance[3], const std::vector<Plane>& fit_a,
                                const std::vector<Plane>& fit_b)
{
    std::vector<Plane> mse;
    for (int c = 0; c < 3; ++c) {
        Plane m(fit_a[c].width, fit_a[c].height);
        for (size_t i = 0; i < m.size(); ++i) {
            float a = half_a[c]->px[i], b = half_b[c]->px[i], v = variance[c]->px[i];
            float fa = fit_a[c].px[i], fb = fit_b[c].px[i];
            float mse_a = (b - fa) * (b - fa) - 2.0f * v;
            float mse_b = (a - fb) * (a - fb) - 2.0f * v;
            float residual = 0.25f * (fb - fa) * (fb - fa);
            m.px[i] = sanitize(0.5f * (mse_a + mse_b) - residual);
        }
        mse.push_back(std::move(m));
    }
    return mse;
}

std::vector<Plane> sure_mse(const Plane* const render[3], const Plane* const variance[3],
                            const Plane probe[3], double eps, const std::vector<Plane>& fit,
                            const std::vector<Plane>& probed_fit)
{
    std::vector<Plane> mse;
    for (int c = 0; c < 3; ++c) {
        Plane m(fit[c].width, fit[c].height);
        for (size_t i = 0; i < m.size(); ++i) {
            const double residual = double(fit[c].px[i]) - render[c]->px[i];
            const double divergence =
                eps > 0 ? probe[c].px[i] * (double(probed_fit[c].px[i]) - fit[c].px[i]) / eps : 0.0;
            m.px[i] = sanitize(float(residual * residual + 2.0 * divergence - variance[c]->px[i]));
        }
        mse.push_back(std::move(m));
    }
    return mse;
}

std::vector<Plane> select_candidate(const std::vector<Plane>& mse0, const std::vector<Plane>& mse1)
{
    std::vector<Plane> selection;
    for (int c = 0; c < 3; ++c) {
        Plane s(mse0[c].width, mse0[c].height);
        for (size_t i = 0; i < s.size(); ++i)
            s.px[i] = mse0[c].px[i] < mse1[c].px[i] ? 0.0f : 1.0f;
        selection.push_back(std::move(s));
    }
    return selection;
}

}  // namespace mcdn
