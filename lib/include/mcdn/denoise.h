// The one-call denoiser: the best chain the inputs allow, for users who do not choose stages.
//
//   with a colour variance (the renderer's, a -i:as=variance file, or a Tungsten buffer set):
//       cnn -> sure -> mix (net)   KPCN, its SURE error estimate, and PD §4's progressive mix
//                                  of render and denoised image by the network trained for
//                                  the KPCN op, bounded by the t-test: never much worse than
//                                  the better of the two
//   and half buffers too (not with settings denoise.choose=0, nor cross-frame: denoise.frames):
//       cnn -> sure -> choose (nfor) -> mix
//                                  NFOR and its SURE beside the CNN, the two weighed per pixel
//                                  by their SURE (mcdn/choose.h), then the mix
//   without one:
//       cnn                         KPCN alone (SURE and the mix need the variance)
// Where the user has Open Image Denoise's weights (mcdn/oidn.h: $MCDN_OIDN_WEIGHTS or
// <prefix>/share/mcdenoise/oidn/), its network takes the CNN's place, and with a variance our
// CNN is the one choose weighs beside it where the render is clean enough for SURE to tell the
// two apart (ChooseOptions::max_noise): oidn -> sure -> choose (cnn) -> mix, or oidn alone
// (docs/accuracy.md).
// The CNN runs on any size and on whatever features there are; missing ones (albedo, normal,
// depth) are zero, which DenoisePlan names. NFOR alone is not picked: it needs half
// buffers, and where they are, choose keeps it where its SURE says it is the better.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"

namespace mcdn {

/// What denoise() runs on an input, and why, in words a log line can hold.
struct DenoisePlan {
    std::vector<std::string> stages;  // "cnn" or "oidn", "sure", "choose", "mix"
    /// Settings of its stages ("mix.model" -> "net", "choose.with" -> "cnn", denoise.extras
    /// as its denoisers' and choose's "extras"); a setting the caller gives wins.
    std::map<std::string, std::string> settings;
    std::string why;                       // "the input has a colour variance (variance.R,...)"
    std::vector<std::string> zero_filled;  // features the CNN reads as zero: "albedo", ...

    /// One line: "cnn -> sure -> mix (net): <why>; zero-filled: albedo".
    std::string describe() const;
};

/// Plans the chain for a merged buffer (io.h) and the AOV spec; false with `error` when the
/// buffer has no colour at all. `settings` as DenoiseOptions' (oidn.weights: where OIDN's
/// weights are, else mcdn/oidn.h's places).
bool plan_denoise(DenoisePlan& plan, const ImageSpec& merged, const AovSpec& aovs,
                  std::string& error, const std::map<std::string, std::string>& settings = {});

/// Whether `stage` (prefilter, nfor, cnn, sure, mix) can run on a resolved AOV set; `how`
/// says how it will run or what it lacks ("one-buffer: no half buffers", "needs the
/// colour's variance").
bool stage_can_run(const std::string& stage, const AovSet& aovs, std::string& how);

struct DenoiseOptions {
    AovSpec aovs;
    /// Stage settings "stage.key" -> value, as in ChainOptions (cnn.tile=256, mix.ttest=0).
    std::map<std::string, std::string> settings;
    /// Given to every stage (mcdn/progress.h).
    ProgressCallback progress;
};

/// dst = src denoised by the planned chain (run_chain), colour role replaced; src's other
/// channels kept as the chain keeps them.
bool denoise(ImageBuf& dst, const ImageBuf& src, const DenoiseOptions& options = {}, ROI roi = {},
             int nthreads = 0);
ImageBuf denoise(const ImageBuf& src, const DenoiseOptions& options = {}, ROI roi = {},
                 int nthreads = 0);

}  // namespace mcdn
