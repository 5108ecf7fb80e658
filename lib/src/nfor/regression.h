// Collaborative first-order regression (NFOR §5.2 and §6).
//
// For every pixel p, a weighted least-squares fit of the colour in the (2R+1)² window around
// p with the design [1, dx, dy, f(q) - f(p)] and NL-means weights w(p, q) from the guide
// colour (eq. 3-6, channels combined by their largest distance). The fit is evaluated at every
// q of the window and accumulated with weight w(p, q) (collaborative filtering, eq. 10); each
// pixel's result is the weighted mean of all fits that cover it.
#pragma once

#include <vector>

#include "core/planar.h"

namespace mcdn {

struct ConvergedTiles;

/// One frame's planes of a fit: the colour fitted, the guide colour of the NL-means weights
/// and its variance (× variance_scale), the features of the design.
struct RegressionFrame {
    const Plane* image[3] = {};
    const Plane* guide[3] = {};
    const Plane* variance[3] = {};
    std::vector<const Plane*> features;
};

struct RegressionInputs {
    const Plane* image[3] = {};     // colour to fit
    const Plane* guide[3] = {};     // colour the NL-means weights are computed on
    const Plane* variance[3] = {};  // variance of the guide (× variance_scale)
    std::vector<const Plane*> features;
    /// A spatio-temporal window (NFOR §8): other frames, aligned to this one (warped by the
    /// motion vectors, ops/motion.h), whose (2R+1)² windows join every fit, weighted by the
    /// patch distance between this frame's guide at p and theirs at q. Each has the same
    /// features in the same order (the caller adds the frame offset as one). The fits are
    /// evaluated on this frame only: the result is this frame's.
    std::vector<RegressionFrame> other_frames;
    int window_radius = 9;
    int patch_radius = 3;
    /// NL-means bandwidths: one fit per k, sharing the patch distances (weights
    /// exp(-d²(k=1) / k²); the reference's ε and clamp make no difference at these scales).
    std::vector<float> bandwidths = { 1.0f };
    float variance_scale = 2.0f;
    /// Use the kernel for any design size even where an unrolled one exists (tests).
    bool any_size_kernel = false;
    /// Tiles not fitted (mcdn/skip.h): their windows add nothing to the neighbours, and
    /// their result is `image` unchanged. nullptr: every tile.
    const ConvergedTiles* skip_tiles = nullptr;
};

/// Most features a regression takes (design columns = 3 + this).
constexpr int kMaxRegressionFeatures = 13;
/// Most frames of a spatio-temporal window (this one and ±4).
constexpr int kMaxRegressionFrames = 9;

/// Returns the three filtered colour planes of each bandwidth. Deterministic for any thread
/// count.
std::vector<std::vector<Plane>> collaborative_regression(const RegressionInputs& inputs,
                                                         int nthreads);

/// Floating-point operations of one collaborative_regression per pixel (for the benchmark's
/// FLOP rate): weights, normal equations, solve and collaborative evaluation.
double regression_flops_per_pixel(int num_features, int window_radius, int patch_radius);

}  // namespace mcdn
