// Large frames in bands. A local op — each output pixel depends on the input within a known
// radius — runs on overlapping horizontal bands, so its working memory follows the band, not
// the frame: NFOR holds ~70 full-frame float planes (9 GB at 7680×4320) when run whole.
#pragma once

#include <cstdint>
#include <functional>

#include <OpenImageIO/imagebuf.h>

#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

using OIIO::ImageBuf;
using OIIO::ImageSpec;
using OIIO::ROI;

using BandOp = std::function<bool(ImageBuf& dst, const ImageBuf& src)>;

/// One horizontal band of a frame: the rows it computes, [own_begin, own_end), and the rows
/// it reads, `cut` (its own rows and up to `halo` more above and below, clipped to the frame).
struct Band {
    ROI cut;
    int own_begin = 0, own_end = 0;
};

/// The bands run_in_bands cuts `whole` into: one band (the whole frame) when it has at most
/// band_pixels pixels or band_pixels <= 0; else at least two bands of equal cuts (own rows
/// and halos): at most band_pixels own pixels each, a halo's rows more for the first and the
/// last, starts and halos rounded to whole converged tiles (mcdn/skip.h).
std::vector<Band> plan_bands(const ROI& whole, int halo, int64_t band_pixels);
/// How many bands run_in_bands (run_local_op) runs src in: 1 when it runs it whole.
int band_count(const ROI& whole, int halo, int64_t band_pixels);

/// Writes the rows of `band_plane` (whose row 0 is frame row band_y) inside `roi` into
/// channel `channel` of `frame`.
void write_rows(ImageBuf& frame, int channel, const Plane& band_plane, int band_y, ROI roi);
/// The same for several planes at once (planes[i] into channels[i]): one pass over the
/// rows of a float frame in memory (a plane at a time would stride through every channel
/// of the frame once per plane).
void write_rows(ImageBuf& frame, const std::vector<int>& channels,
                const std::vector<const Plane*>& band_planes, int band_y, ROI roi);

/// Runs `op` on src whole when src has at most `band_pixels` pixels (or band_pixels <= 0).
/// Otherwise cuts src into horizontal bands of at most band_pixels pixels, each with `halo`
/// more rows above and below (its own data window inside src's), runs `op` on each and
/// assembles dst from the bands' own rows. When `halo` covers the op's receptive radius the
/// result equals the whole-frame run. Rows and halos are rounded up to whole converged tiles
/// (mcdn/skip.h) so that skipping decides per tile as on the whole frame. dst may be src.
/// Errors go on dst.
bool run_in_bands(ImageBuf& dst, const ImageBuf& src, int halo, int64_t band_pixels,
                  const BandOp& op);

/// How a local op runs: in bands (above), each band converted to the working colour space
/// and back (mcdn/color.h run_in_working_space).
bool run_local_op(ImageBuf& dst, const ImageBuf& src, const AovSpec& aovs, const char* op_name,
                  int halo, int64_t band_pixels, const BandOp& op);

}  // namespace mcdn
