// What the chain's files share (chain.cpp runs stages, chain_bands.cpp cuts frames into bands).
#pragma once

#include <string>

#include "mcdn/chain.h"
#include "mcdn/denoise.h"

namespace mcdn {

/// `o` with a plan (a chain of the one stage "denoise") replaced by the chain it plans for a
/// frame of `spec` (mcdn/denoise.h): its stages, and its settings where `o` has none of its
/// own. `plan` (when given) gets the plan. A chain of stages comes back as it is.
bool planned_chain(ChainOptions& planned, const ImageSpec& spec, const ChainOptions& o,
                   std::string& error, DenoisePlan* plan = nullptr);

/// mcdn::run_chain on the whole of a src that is the caller's own (a band it read or cut,
/// a frame it read), which it uses up: sure probes src itself instead of a copy
/// (sure/sure_steps.h sure_probing_src) and src is released once sure is done; denoisers
/// after the last sure (or with none) run in place on it. A band then costs no frame-sized
/// copy of itself. src is left empty or changed; nothing else may read it meanwhile.
bool run_chain_on_own(ImageBuf& dst, ImageBuf& src, const ChainOptions& options, int nthreads);

/// A stage's error as the chain reports it: behind the stage's name, once (the stages name
/// themselves in some of their errors: "cnn: cnn: ..." otherwise).
inline std::string stage_error(const std::string& stage, const std::string& error)
{
    return error.compare(0, stage.size() + 2, stage + ": ") == 0 ? error : stage + ": " + error;
}

}  // namespace mcdn
