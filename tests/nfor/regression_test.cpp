// The regression's kernels: the unrolled kernel of a common design size and the kernel for
// any size compute the same sums in the same order, and solve the same systems.
#include <cmath>

#include <gtest/gtest.h>

#include "nfor/regression.h"
#include "nfor_support.h"

using namespace mcdn;

TEST(NforRegression, UnrolledAndAnySizeKernelsAgree)
{
    const int w = 70, h = 45;  // partial tiles on both axes
    std::vector<Plane> planes;
    for (int p = 0; p < 3 + 3 + 7; ++p) {  // image, guide (= variance source), features
        Plane plane(w, h);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                plane(x, y) = 0.5f + 0.2f * std::sin(0.1f * x * (p + 1) + 0.07f * y)
                              + 0.05f * nfor_test::gauss(x, y, p);
        planes.push_back(std::move(plane));
    }
    Plane variance(w, h, 0.0025f);
    RegressionInputs in;
    for (int c = 0; c < 3; ++c) {
        in.image[c] = &planes[c];
        in.guide[c] = &planes[3 + c];
        in.variance[c] = &variance;
    }
    for (int k = 0; k < 7; ++k)  // 7 features: the unrolled D = 10 kernel
        in.features.push_back(&planes[6 + k]);
    in.features[6] = in.features[5];  // a collinear column: dropped by the solve
    in.bandwidths = { 0.5f, 1.0f };
    auto unrolled = collaborative_regression(in, 1);
    in.any_size_kernel = true;
    auto any_size = collaborative_regression(in, 2);
    for (int j = 0; j < 2; ++j)
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < unrolled[j][c].size(); ++i) {
                ASSERT_TRUE(std::isfinite(unrolled[j][c].px[i]));
                ASSERT_NEAR(unrolled[j][c].px[i], any_size[j][c].px[i],
                            1e-4f * (1 + std::abs(unrolled[j][c].px[i])))
                    << "bandwidth " << j << " channel " << c << " pixel " << i;
            }
}
