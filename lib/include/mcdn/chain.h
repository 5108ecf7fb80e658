// A chain of stages by name, e.g. "prefilter,nfor,sure,mix", for front ends that take a
// recipe rather than commands (the oiiotool format plugin, Python's run_chain). Denoisers
// before "sure" form the denoiser SURE estimates the error of; "mix" needs "sure" first.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/threads.h"

namespace mcdn {

struct ChainOptions {
    AovSpec aovs;
    /// Stage names in order: prefilter, nfor, cnn, sure, mix; or "denoise" alone, the best
    /// chain the inputs allow (mcdn/denoise.h).
    std::vector<std::string> stages = { "denoise" };
    /// Per-stage settings "stage.key" -> value: nfor.window=19, sure.probes=4,
    /// mix.model=net, mix.ttest=0, ... (the same keys as mcdntool's modifiers).
    std::map<std::string, std::string> settings;
    /// Given to every stage (mcdn/progress.h).
    ProgressCallback progress;
    /// Pixels of one band of rows, halos not counted. A larger frame runs through the whole
    /// chain one band at a time, each with chain_reach() rows of halo: the frame's statistics
    /// (SURE's probe step, the t-test's sigma_s, the CNN's depth range, constant features)
    /// are fixed by a light pass over it first, so the result is the whole frame's (the
    /// mixing network's to float round-off: its tiles fall differently), and memory follows
    /// the band, not the frame. 0: the whole frame at once.
    int64_t band_pixels = kChainBandPixels;
    /// A band holds at least this many times the chain's halo in rows of its own, band_pixels
    /// or not: the rows each band computes again for the bands beside it are then at most 2 /
    /// band_halos of its own. 8K --oidn (halo 128): bands of 256 rows computed the frame's
    /// rows 2.0 times (489 s, 3.14 GiB), of 384 rows 1.8 times (413 s, 3.70 GiB), of 480 rows
    /// 1.5 times (375 s, but 4.04 GiB). 0: band_pixels alone decides.
    int band_halos = 3;
    /// The caller keeps only the input's output channels of the result ("mcdn:output_channels",
    /// what -o writes: mcdntool's chain into one -o). After a prefilter only the features'
    /// output channels are then put back (and kept apart for it), the others (their
    /// variances and halves) are left as the prefilter made them.
    bool output_channels_only = false;
};

/// What a chain's result says on its spec of the safety nets (the tiles each left as the
/// render: mcdn/nfor.h, mcdn/sure.h) and of choose's share (mcdn/choose.h), over a frame
/// made in bands: add() each band's result spec, set() the frame's. Counts are summed (a
/// tile of two bands' halos counts twice), the share is the mean over the bands' pixels,
/// choose's estimate the last band's (every band's is the same).
/// run_chain's gathered result carries them so; a front end with a BandSink keeps its own.
class BandCounts {
public:
    void add(const ImageSpec& band);
    /// Replaces the counts and the share on `frame` (those absent from every band: erased).
    void set(ImageSpec& frame) const;

private:
    int64_t tiles_[3] = {};  // nfor's fallback, sure's fallback, sure's worse tiles
    double share_sum_ = 0, share_pixels_ = 0;
    std::string estimate_;
};

/// $MCDN_BAND_PIXELS, when set, as `options`' bands, exactly (band_halos 0; 0: the whole
/// frame at once): every front end's knob of memory against speed (docs/performance.md).
/// Unset or not a number: left as they are.
void set_bands_from_environment(ChainOptions& options);

/// The rows [own.ybegin, own.yend) of a chain's result, every channel, in `band` (which may
/// hold more rows: its halo); false with `error` to stop the chain.
using BandSink = std::function<bool(const ImageBuf& band, const ROI& own, std::string& error)>;

/// Parses "prefilter,nfor,sure,mix" (or "denoise") and checks the order; false with `error`
/// on an unknown stage or a mix without a sure before it.
bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error);

/// Copies the named channels of `input` into the same-named channels of dst; false with
/// `error` when either lacks one.
bool copy_channels_by_name(ImageBuf& dst, const ImageBuf& input,
                           const std::vector<std::string>& names, std::string& error);

/// Runs the chain on src (a merged buffer, io.h). dst as the last stage leaves it, except
/// that a prefilter's features are replaced by src's own unless prefilter.features-out or
/// nfor.features-out is set.
bool run_chain(ImageBuf& dst, const ImageBuf& src, const ChainOptions& options, ROI roi = {},
               int nthreads = 0);

/// The same, in bands (ChainOptions::band_pixels), each band's own rows handed to `sink` top
/// to bottom as soon as they are made (a writer can stream them to a file): nothing
/// frame-sized is allocated but src. false with `error` (or sink's).
bool run_chain(const ImageBuf& src, const ChainOptions& options, const BandSink& sink,
               std::string& error, int nthreads = 0);

/// Rows [ybegin, yend) of a frame, every channel of its spec, as a float buffer of those
/// rows (mcdn::InputRows::read); `channels`, when not empty, marks the ones the caller looks
/// at (the others may be left zero). false with `error` stops the chain.
using RowReader = std::function<bool(ImageBuf& rows, int ybegin, int yend,
                                     const std::vector<bool>& channels, std::string& error)>;

/// The same on a frame never in memory whole: `frame` is its spec (no pixels), `read` gives
/// its rows. The light pass reads the frame once (only the channels it needs), then every band
/// is read with its halo: peak memory follows the band. A frame of one band is read whole.
/// The result is that of the chain on the frame read whole.
bool run_chain(const ImageSpec& frame, const RowReader& read, const ChainOptions& options,
               const BandSink& sink, std::string& error, int nthreads = 0);

/// How far a pixel of the chain's result reaches into its input: the sum of its stages'
/// receptive radii (the halo of its bands); -1 when one is unknown.
int chain_reach(const ImageSpec& spec, const ChainOptions& options);

/// A band of a chain that reaches `reach` pixels (chain_reach) across a frame `width` pixels
/// wide: its own pixels, ChainOptions::band_pixels raised to band_halos halos, and the rows
/// of halo it reads each side, `reach` rounded up to whole converged tiles (mcdn/skip.h).
struct ChainBand {
    int64_t own_pixels = 0;
    int halo_rows = 0;
};
ChainBand chain_band(int width, const ChainOptions& options, int reach);

}  // namespace mcdn
