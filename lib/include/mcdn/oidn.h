// Intel Open Image Denoise's published networks on our engine: the user's copy of OIDN's
// weights (`rt_hdr_alb_nrm.tza` and its siblings, Apache 2.0, from RenderKit/oidn-weights or
// any OIDN 2.x package; we never ship them) read by our own reader and run by our oneDNN
// engine, tiled and deterministic, as a denoiser stage our SURE and progressive mix can wrap
// (Progressive Denoising §6 runs its mix over the pre-trained OIDN).
//
//   model   picked by the inputs: colour + albedo + normal: rt_hdr_alb_nrm; colour +
//           albedo: rt_hdr_alb; colour alone: rt_hdr (a normal without an albedo is not
//           read: OIDN has no such model). With OidnOptions::prefilter, OIDN's own networks
//           for the albedo and the normal (rt_alb, rt_nrm) clean them first and
//           rt_hdr_calb_cnrm reads the clean ones (OIDN's cleanAux; Blender's "Accurate")
//   in      colour × the autoexposure scale (0.18 over the geometric mean of ~16×16-pixel
//           bins' luminances, over the whole frame), through the PU transfer function
//           normalised at 65504; albedo clamped to [0, 1]; normal clamped to [-1, 1] and
//           mapped to [0, 1]
//   net     OIDN's UNet (lib/src/oidn/oidn_steps.h), tiled with a halo of its receptive
//           field, the image extended to a multiple of 16
//   out     the inverse transfer of the output clamped at 0, divided by the scale
// Heavy-tailed pixels (OidnOptions::outliers) enter the network as their neighbourhood's
// median, as they enter our CNN.
#pragma once

#include <string>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/skip.h"

namespace mcdn {

struct OidnOptions {
    AovSpec aovs;
    /// A `.tza` file, or a folder holding OIDN's files by their names (rt_hdr_alb_nrm.tza,
    /// rt_hdr_alb.tza, rt_hdr.tza); empty: $MCDN_OIDN_WEIGHTS (a file or a folder), else
    /// <prefix>/share/mcdenoise/oidn/ (oidn_weights_dir()). A file's first convolution
    /// says which inputs it reads (3: colour, 6: + albedo, 9: + normal).
    std::string weights;
    /// Denoise the AOV set's extra AOVs (AovSpec::extras, light groups) too, each by the
    /// network with the beauty's features and exposure, then shared so that extras which add
    /// up to the beauty still do (to float rounding); false: keep them as rendered.
    bool denoise_extras = true;
    /// Output tile side of the tiled inference, run a tile at a time with every thread in
    /// its layers: a window (the tile and its halo) holds at most (tile + 2 × halo)² pixels,
    /// in a grid that splits the frame evenly (nn::TileOptions::balanced), so memory follows
    /// that, not the frame nor the threads; the output does not depend on it. Larger tiles
    /// recompute less of their halo (1080p: two windows at 1024, three at 768).
    int tile_size = 1024;
    /// Heavy-tailed samples (a caustic through glass, a firefly), by the rule and thresholds
    /// of NFOR's and the CNN's (lib/src/outliers/outliers.h): such a pixel's colour becomes
    /// its 5×5 neighbourhood's median in the network's input and its excess is dropped, as a
    /// renderer's sample clamp would; otherwise the network spreads it into a blotch. Needs
    /// the colour's variance (else nothing is taken out).
    enum class Outliers {
        Drop,  ///< taken out of the input, their excess dropped (the default)
        Off,   ///< every pixel as rendered
    };
    Outliers outliers = Outliers::Drop;
    /// Prefilter the albedo and the normal with OIDN's networks for them (rt_alb: in and out
    /// through the sRGB curve on [0, 1]; rt_nrm: [-1, 1] mapped to [0, 1] and back), then
    /// denoise with its model for clean features (rt_hdr_calb_cnrm), as OIDN's cleanAux and
    /// Blender's "Accurate" prefilter do. Needs an albedo and a normal and the two prefilters'
    /// files beside the model. Two more networks' work, once per frame (the extras share the
    /// clean features); the reach doubles. Measured on box (relMSE): 16 spp +4 %, 64 spp
    /// -7 %, 256 spp -17 %; tungsten cornell20 +13 %, materialtest -5 %: better where the
    /// features' own noise limits the result (high sample counts, depth of field), not always
    /// at low ones.
    bool prefilter = false;
    /// Converged tiles are the render (mcdn/skip.h).
    SkipOptions skip;
    ProgressCallback progress;
};

/// <prefix>/share/mcdenoise/oidn: where a user puts OIDN's weight files for every user.
std::string oidn_weights_dir();

/// The weights file oidn() reads for inputs with or without an albedo and a normal
/// (rt_hdr_calb_cnrm with both and OidnOptions::prefilter); false with `error` naming the
/// places looked in and where OIDN's weights come from.
bool oidn_weights(std::string& path, const OidnOptions& options, bool has_albedo, bool has_normal,
                  std::string& error);

/// How far a pixel of oidn()'s result reaches into its input (the UNet's receptive field;
/// -1 when no weights can be read).
int receptive_radius(const OidnOptions& options);

/// dst = src with the colour role replaced by OIDN's network's estimate (inside `roi`; every
/// other channel kept, the extras denoised as OidnOptions::denoise_extras says). Needs the colour;
/// reads the albedo and normal where present. Deterministic for any `nthreads` (0 = all cores).
bool oidn(ImageBuf& dst, const ImageBuf& src, const OidnOptions& options = {}, ROI roi = {},
          int nthreads = 0);
ImageBuf oidn(const ImageBuf& src, const OidnOptions& options = {}, ROI roi = {}, int nthreads = 0);

}  // namespace mcdn
