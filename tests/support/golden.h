// Golden-image comparison in the manner of idiff: per-pixel and mean thresholds, and a
// failure report that lists the worst pixels. Regenerate goldens on purpose with
//   MCDN_UPDATE_GOLDENS=1 ctest --test-dir build -L golden
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include <OpenImageIO/imagebufalgo.h>

#include "core/simd.h"
#include "mcdn/io.h"

#include "mcdn_test.h"

namespace mcdn_test {

struct GoldenThresholds {
    /// A pixel fails when |a - g| > absolute + relative * |g| in any channel. The relative
    /// part absorbs AVX-512 vs AVX2 vs portable float differences between machines.
    double absolute = 1e-4, relative = 2e-3;
    /// The mean |a - g| / (|g| + 0.01) over all values must stay below this.
    double mean_relative = 2e-4;
    /// Failing pixels allowed, as a fraction (idiff's -failpercent / 100).
    double fail_fraction = 0.0;
};

inline bool update_goldens()
{
    const char* env = std::getenv("MCDN_UPDATE_GOLDENS");
    return env && std::string(env) == "1";
}

/// Compares channels `names` of `result` with tests/data/golden/<name>.exr; in update mode
/// writes it instead. Returns a gtest assertion result carrying the report.
inline ::testing::AssertionResult matches_golden(const OIIO::ImageBuf& result,
                                                 const std::vector<std::string>& names,
                                                 const std::string& name, GoldenThresholds t = {})
{
    std::string path = test_data("golden/" + name + ".exr");
    std::vector<int> order;
    for (const auto& n : names) {
        int c = result.spec().channelindex(n);
        if (c < 0)
            return ::testing::AssertionFailure() << "result has no channel " << n;
        order.push_back(c);
    }
    OIIO::ImageBuf picked = OIIO::ImageBufAlgo::channels(result, int(order.size()), order);
    // Goldens record the instruction set they were made with: NL-means weights and the
    // per-pixel bandwidth choice turn float differences between kernels into visible ones.
    const std::string isa = mcdn::isa_name(mcdn::detect_isa());
    if (update_goldens()) {
        picked.specmod().attribute("mcdn:isa", isa);
        mcdn::WriteOptions o;
        o.channels = names;
        std::string error;
        if (!mcdn::write_image(picked, path, o, error))
            return ::testing::AssertionFailure() << error;
        return ::testing::AssertionSuccess() << "updated " << path;
    }
    OIIO::ImageBuf golden;
    if (!mcdn::read_image(golden, path))
        return ::testing::AssertionFailure()
               << golden.geterror() << " (create it with MCDN_UPDATE_GOLDENS=1)";
    std::string golden_isa = golden.spec().get_string_attribute("mcdn:isa");
    if (golden_isa != isa) {
        // Reported as a skip, not a pass: the FMA contraction of each instruction set (and
        // compiler flags: GCC fuses only from -O2 on) moves NFOR's output by ~1e-3.
        [&] {
            GTEST_SKIP() << "golden " << name << " was made with " << golden_isa
                         << " kernels, this machine runs " << isa
                         << ": not compared (regenerate on this machine type)";
        }();
        return ::testing::AssertionSuccess();
    }
    // EXR stores channels sorted by name: match them by name, not position.
    std::vector<int> golden_order;
    for (const auto& n : names) {
        int c = golden.spec().channelindex(n);
        if (c < 0)
            return ::testing::AssertionFailure() << path << " has no channel " << n;
        golden_order.push_back(c);
    }
    golden = OIIO::ImageBufAlgo::channels(golden, int(golden_order.size()), golden_order);
    const auto &ps = picked.spec(), &gs = golden.spec();
    if (ps.width != gs.width || ps.height != gs.height)
        return ::testing::AssertionFailure() << name << ": size differs from the golden";
    struct Bad {
        double excess;
        int x, y, c;
        float got, want;
    };
    std::vector<Bad> bad;
    double mean = 0;
    size_t n = 0;
    for (int y = 0; y < ps.height; ++y)
        for (int x = 0; x < ps.width; ++x) {
            std::vector<float> a(ps.nchannels), g(ps.nchannels);
            picked.getpixel(ps.x + x, ps.y + y, a.data(), ps.nchannels);
            golden.getpixel(gs.x + x, gs.y + y, g.data(), gs.nchannels);
            for (int c = 0; c < ps.nchannels; ++c) {
                double d = std::fabs(double(a[c]) - g[c]);
                mean += d / (std::fabs(g[c]) + 0.01);
                ++n;
                double allowed = t.absolute + t.relative * std::fabs(g[c]);
                if (!(d <= allowed))
                    bad.push_back({ d / allowed, x, y, c, a[c], g[c] });
            }
        }
    mean /= std::max<size_t>(n, 1);
    double fail_fraction = double(bad.size()) / std::max<size_t>(n, 1);
    if (fail_fraction <= t.fail_fraction && mean <= t.mean_relative)
        return ::testing::AssertionSuccess();
    std::sort(bad.begin(), bad.end(),
              [](const Bad& a, const Bad& b) { return a.excess > b.excess; });
    auto failure = ::testing::AssertionFailure();
    failure << name << ": " << bad.size() << " values over the per-pixel threshold ("
            << 100 * fail_fraction << "%), mean relative difference " << mean << " (limit "
            << t.mean_relative << "); worst:";
    for (size_t i = 0; i < std::min<size_t>(bad.size(), 5); ++i)
        failure << "\n  (" << bad[i].x << ", " << bad[i].y << ") " << names[bad[i].c] << ": got "
                << bad[i].got << ", golden " << bad[i].want;
    failure
        << "\nIf the change is intended: MCDN_UPDATE_GOLDENS=1 ctest --test-dir build -L golden";
    return failure;
}

}  // namespace mcdn_test
