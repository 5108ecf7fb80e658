// Error of an image against a converged reference: the numbers users compare stages by.
//
//   MSE     mean (x - r)^2
//   RMSE    sqrt(MSE)
//   relMSE  mean (x - r)^2 / (r^2 + 0.01)                        (NFOR, KPCN, PD)
//   SMAPE   mean |x - r| / (|x| + |r| + 0.01)                     (PD)
//   PSNR    10 log10(1 / MSE): peak 1.0, the display white of scene-linear images
//   SSIM    mean SSIM, Gaussian window sigma 1.5 (11x11), C1 = 0.01^2, C2 = 0.03^2, on
//           values clamped to [0, 1] (SSIM's constants assume that range)
// All are means over pixels and the chosen channels. With `trim`, each per-pixel error
// (averaged over channels) drops the trim_fraction best and worst pixels before the mean,
// as KPCN reports relMSE (0.01% each side).
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

using OIIO::ImageBuf;
using OIIO::ROI;

struct MetricsOptions {
    /// Channels of the image and of the reference, in matching order (3 for RGB).
    std::vector<int> image_channels = { 0, 1, 2 };
    std::vector<int> reference_channels = { 0, 1, 2 };
    bool trim = false;
    double trim_fraction = 1e-4;  // KPCN: drop 0.01% best and worst
    double relmse_epsilon = 0.01;
    double smape_epsilon = 0.01;
};

struct Metrics {
    double mse = 0, rmse = 0, relmse = 0, smape = 0, psnr = 0, ssim = 0;
    long long pixels = 0;  // pixels in the mean (after trimming)
};

/// Computes every metric of `image` against `reference` over `roi` (default: the whole
/// image). Sizes must agree; non-finite pixels are an error. Errors go to `error`.
bool compute_metrics(Metrics& result, const ImageBuf& image, const ImageBuf& reference,
                     const MetricsOptions& options, std::string& error, ROI roi = {},
                     int nthreads = 0);

/// Which per-pixel error a heatmap shows.
enum class ErrorKind { RelMSE, SquaredError, AbsoluteError, SMAPE };

/// Per-pixel error (mean over the chosen channels) as a one-channel float image.
bool error_map(ImageBuf& dst, const ImageBuf& image, const ImageBuf& reference,
               const MetricsOptions& options, ErrorKind kind, ROI roi = {}, int nthreads = 0);

/// False-colour picture of an error map: log10(error) from `log10_min` to `log10_max`
/// mapped through the "inferno" colour map (OIIO IBA::color_map), RGB in [0, 1], ready for
/// PNG. Pixels below the range are black, above it pale yellow.
bool heatmap(ImageBuf& dst, const ImageBuf& error, double log10_min = -4.0,
             double log10_max = 0.0, ROI roi = {}, int nthreads = 0);

/// `name value` lines (text) or one JSON object, for the CLI and the benchmarks.
std::string format_metrics(const Metrics& m, bool json);

}  // namespace mcdn
