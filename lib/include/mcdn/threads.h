// Worker threads and bands: the one rule every op and front end applies to a thread count,
// and the sizes of the bands of rows ops and chains run large frames in.
#pragma once

#include <cstdint>
#include <string>

namespace mcdn {

/// Every op runs on `nthreads` workers: 0 means all cores, otherwise 1 to kMaxThreads.
/// Larger counts are errors, not clamps (TBB's arenas crash far beyond any machine's cores).
constexpr int kMaxThreads = 1024;

/// False with `error` ("threads=70000: needs a whole number from 0 (all cores) to 1024")
/// when `nthreads` is out of range.
bool check_threads(int nthreads, std::string& error);

/// A typed thread count (--threads N, recipe threads=N): digits only, then check_threads.
bool parse_threads(const std::string& text, int& nthreads, std::string& error);

/// Starts the workers `nthreads` (0: all cores) will use, TBB's and the network engine's
/// OpenMP ones, now: a process whose memory runs out later (an address-space limit) then
/// never has to create a thread, which TBB and OpenMP cannot fail without aborting.
/// mcdntool calls it before its first frame.
void start_threads(int nthreads);

/// Pixels of one band of rows (halos not counted) of an op run alone on a large frame
/// (NforOptions::band_pixels, PrefilterOptions', MixOptions'): its per-pixel buffers for a
/// band, not the frame.
constexpr int64_t kOpBandPixels = int64_t(1) << 22;
/// The same for a chain of stages (ChainOptions::band_pixels) and for SURE, which holds its
/// denoiser's buffers besides its own: half an op's band.
constexpr int64_t kChainBandPixels = int64_t(1) << 21;

}  // namespace mcdn
