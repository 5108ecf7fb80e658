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

/// relMSE's offset: errors relative to the reference's r^2 + kRelMseOffset, so that dark
/// pixels do not dominate (NFOR, KPCN, PD). Every relative error in the library uses it.
constexpr double kRelMseOffset = 0.01;

struct MetricsOptions {
    /// Channels of the image and of the reference, in matching order (3 for RGB).
    std::vector<int> image_channels = { 0, 1, 2 };
    std::vector<int> reference_channels = { 0, 1, 2 };
    bool trim = false;
    double trim_fraction = 1e-4;  // KPCN: drop 0.01% best and worst
    double relmse_epsilon = kRelMseOffset;
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

/// Flicker of a sequence: how a frame's error changes from the frame before, after motion
/// compensation. With e_t = x_t - r_t the error of frame t and W the bilinear warp of frame
/// t-1 onto frame t by the motion (pixel p of frame t was at p + m(p) in frame t-1):
///   temporal MSE     mean (e_t - W e_{t-1})^2
///   temporal relMSE  mean (e_t - W e_{t-1})^2 / (r_t^2 + 0.01)
/// that is, the error of the frame-to-frame difference x_t - W x_{t-1} against the
/// reference's r_t - W r_{t-1}: an error that moves with the picture does not flicker and
/// counts 0; noise drawn anew every frame counts about twice its per-frame MSE. Pixels
/// whose previous position lies outside frame t-1 are left out. Channels and trimming as
/// MetricsOptions (trimmed on the per-pixel temporal error).
struct TemporalOptions {
    MetricsOptions metrics;
    /// The motion buffer's two channels (x, y), times their scales, give m in pixels, +y
    /// down the image (OIIO's rows); no motion buffer: m = 0. Cycles' Vector pass is X, Y
    /// with scales (1, -1): its X, Y point to frame t-1 in Blender's raster, y up.
    int motion_x = 0, motion_y = 1;
    double motion_scale_x = 1.0, motion_scale_y = 1.0;
};

struct TemporalMetrics {
    double mse = 0, relmse = 0;
    long long pixels = 0;  // pixels in the mean (inside frame t-1, after trimming)
};

/// Computes the temporal metrics of `image` (frame t) after `previous` (frame t-1) against
/// their references. Every buffer has the image's size; non-finite pixels are an error.
/// `motion` may be null (a still camera and scene).
bool compute_temporal_metrics(TemporalMetrics& result, const ImageBuf& image,
                              const ImageBuf& previous, const ImageBuf& reference,
                              const ImageBuf& previous_reference, const ImageBuf* motion,
                              const TemporalOptions& options, std::string& error, int nthreads = 0);

/// What a reference's own noise adds to the squared-error metrics. A reference that is
/// itself a render, with variance of the mean v at a pixel, adds v to the expected squared
/// error there, whatever the image is (the image's error is independent of the reference's
/// noise): per frame mean v and mean v / (r^2 + 0.01); per pair of frames mean
/// (v_t + W2 v_{t-1}) and that over (r_t^2 + 0.01), with W2 the warp by the squared bilinear
/// weights, over the pixels the temporal metrics keep. Subtracted from the untrimmed
/// Metrics::mse and ::relmse (TemporalMetrics's), they estimate the error against a
/// converged reference (for relMSE to first order: r in the denominator is the noisy one).
/// A metric near this floor says the reference cannot tell the image's error apart.
struct ReferenceNoise {
    double mse = 0, relmse = 0;
};

/// `variance` is laid out as the reference (options.reference_channels index both).
bool compute_reference_noise(ReferenceNoise& result, const ImageBuf& reference,
                             const ImageBuf& variance, const MetricsOptions& options,
                             std::string& error, ROI roi = {}, int nthreads = 0);

/// The same for compute_temporal_metrics: the variances of reference t and of reference t-1,
/// laid out as reference t; the motion and options as there.
bool compute_temporal_reference_noise(ReferenceNoise& result, const ImageBuf& reference,
                                      const ImageBuf& variance, const ImageBuf& previous_variance,
                                      const ImageBuf* motion, const TemporalOptions& options,
                                      std::string& error, int nthreads = 0);

/// Which per-pixel error a heatmap shows.
enum class ErrorKind { RelMSE, SquaredError, AbsoluteError, SMAPE };

/// Per-pixel error (mean over the chosen channels) as a one-channel float image.
bool error_map(ImageBuf& dst, const ImageBuf& image, const ImageBuf& reference,
               const MetricsOptions& options, ErrorKind kind, ROI roi = {}, int nthreads = 0);

/// False-colour picture of an error map: log10(error) from `log10_min` to `log10_max`
/// mapped through the "inferno" colour map (OIIO IBA::color_map), RGB in [0, 1], ready for
/// PNG. Pixels below the range are black, above it pale yellow.
bool heatmap(ImageBuf& dst, const ImageBuf& error, double log10_min = -4.0, double log10_max = 0.0,
             ROI roi = {}, int nthreads = 0);

/// `name value` lines (text) or one JSON object, for the CLI and the benchmarks.
std::string format_metrics(const Metrics& m, bool json);

}  // namespace mcdn
