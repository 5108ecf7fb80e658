// Kernel-predicting convolutional denoiser (KPCN; Bako et al. 2017, "Kernel-Predicting
// Convolutional Networks for Denoising Monte Carlo Renderings"), sized for CPUs.
//
//   §4.3  the light is split into diffuse = DiffCol·(DiffDir + DiffInd) and specular =
//         everything else (Combined − diffuse, so eq. 4 gives back Combined exactly);
//         diffuse is divided by (albedo + 0.00316), specular goes through log(1 + x)
//   §5.1  variances moved through those transforms (Taylor rule), depth scaled to [0, 1],
//         x/y gradients of colour and features; 34 input channels per branch
//   §4.2  each branch is a small UNet that predicts per-pixel softmax kernels; instead of one
//         21×21 kernel it predicts five 5×5 kernels applied one after the other (the same
//         21×21 footprint: 5·25 weights per pixel and channel instead of 441)
//   eq. 4 the inverse transforms and the sum of the two branches
// Without a diffuse/specular split the specular network denoises log(1 + colour).
// Training: training/cnn (PyTorch); the model: models/kpcn.mcdnw (models/README-kpcn.md).
#pragma once

#include <string>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/skip.h"

namespace mcdn {

struct CnnOptions {
    AovSpec aovs;
    /// The weights file; empty = default_cnn_weights().
    std::string weights;
    /// Denoise the AOV set's extra AOVs (AovSpec::extras, Blender light groups) with the
    /// beauty's kernels: each takes its share of the denoised diffuse and specular, so that
    /// extras which add up to the beauty still do (lib/src/cnn/extras_kernels.h).
    bool denoise_extras = true;
    /// Output tile side of the tiled inference (nn::run_tiled): memory is bounded by
    /// (tile_size + 2 · halo)² × the widest layer, not by the image; each tile recomputes
    /// its halo, so smaller tiles cost more time. The default trades a little time for
    /// memory: a 1080p frame's --cnn --sure --mix stays under 2 GB on two
    /// threads. The output does not depend on it.
    int tile_size = 384;
    /// Heavy-tailed samples (a caustic path through glass, a firefly): a pixel whose one
    /// sample outweighs its neighbourhood by far, by the rule and thresholds of NFOR's
    /// (NforOptions::outliers, lib/src/outliers/outliers.h), is taken out before the
    /// network: its colour and variance become its 5×5 neighbourhood's medians, its diffuse
    /// and specular parts (and extras) are scaled with the colour, and its excess is dropped,
    /// as a renderer's sample clamp would. Otherwise the kernels spread it over their reach:
    /// a blotch. Needs the colour's variance (else nothing is taken out).
    enum class Outliers {
        Drop,  ///< taken out, their excess dropped (the default)
        Off,   ///< every pixel as rendered
    };
    Outliers outliers = Outliers::Drop;
    /// Converged tiles are the render, untouched; the network runs only on rectangles
    /// holding non-converged tiles (each with its receptive-field halo), so pixels within
    /// the halo of a converged tile can differ from an unskipped run (mcdn/skip.h). Feature
    /// AOVs are fixed network inputs: absent ones are zero, constant ones are used as they are.
    SkipOptions skip;
    /// Called as the stage advances (mcdn/progress.h); empty: nothing is reported.
    ProgressCallback progress;
};

/// The weights cnn() runs without CnnOptions::weights, in the models directory ($MCDN_MODELS
/// when set, else the one installed with the library, share/mcdenoise/models:
/// nn::model_file): for a frame (`aovs`) with neither the colour's variance nor the
/// diffuse/specular split, kpcn_can.mcdnw, the network trained on colour, albedo and normal
/// alone (most renderers' output; its depth is zero, a depth pass is not read), where it is
/// installed; kpcn.mcdnw otherwise, and without `aovs`.
std::string default_cnn_weights(const AovSet* aovs = nullptr);
/// The colour + albedo + normal model's file name in the models directory.
constexpr const char* kColourAlbedoNormalWeights = "kpcn_can.mcdnw";

/// How far a pixel of cnn()'s result reaches into its input: the networks' receptive field,
/// their kernels included (-1 when the weights cannot be read).
int receptive_radius(const CnnOptions& options);

/// dst = src with the colour role replaced by the KPCN estimate (written inside `roi`; every
/// other channel of src kept, so ops chain and sure() can wrap it). Needs the colour;
/// uses the diffuse/specular split, albedo, normal, depth and their variances where present
/// (missing features are zero). Deterministic for any `nthreads` (0 = all cores).
bool cnn(ImageBuf& dst, const ImageBuf& src, const CnnOptions& options = {}, ROI roi = {},
         int nthreads = 0);
ImageBuf cnn(const ImageBuf& src, const CnnOptions& options = {}, ROI roi = {}, int nthreads = 0);

/// cnn() keeps its workers (a copy of the networks and their buffers per thread, sized by
/// CnnOptions::tile_size) for the next call: fresh ones are page faults the kernel must
/// clear. This frees them (a pipeline done denoising, or short of memory).
void release_cnn_workers();

}  // namespace mcdn
