// What the chain's files share (chain.cpp runs stages, chain_bands.cpp cuts frames into bands).
#pragma once

#include "mcdn/chain.h"

namespace mcdn {

/// mcdn::run_chain on the whole of a src that is the caller's own (a band it read or cut,
/// a frame it read): sure probes src itself instead of a copy (sure/sure_steps.h
/// sure_probing_src), so a band costs a frame-sized buffer less, and src is released
/// (reset) as soon as no later stage needs it; else it is as it was when this returns.
/// Meanwhile nothing else may read it.
bool run_chain_on_own(ImageBuf& dst, ImageBuf& src, const ChainOptions& options, int nthreads);

}  // namespace mcdn
