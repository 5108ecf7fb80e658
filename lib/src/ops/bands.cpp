// Large frames in bands (bands.h).
#include "ops/bands.h"

#include <algorithm>
#include <cstring>

#include <OpenImageIO/imagebufalgo.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mcdn/color.h"
#include "mcdn/skip.h"

namespace mcdn {

std::vector<Band> plan_bands(const ROI& whole, int halo, int64_t band_pixels)
{
    const int64_t width = std::max<int64_t>(1, whole.width());
    const int height = whole.height();
    if (band_pixels <= 0 || int64_t(whole.npixels()) <= band_pixels)
        return { Band { whole, whole.ybegin, whole.yend } };
    // Bands of equal cuts: the first and the last, with a halo on one side only, own a
    // halo's rows more than the others, which own at most band_pixels. Every band's buffers
    // are then the same size, so a band fits in the memory the band before it freed
    // (mcdntool keeps freed memory in the process): a second band a halo taller than the
    // first took its own besides (4K --denoise: 4.0 GB after the first band, 4.5 after).
    // Where the halos leave no rows between them, equal own rows (every cut is then most of
    // the frame). Band starts, cuts and halos are whole converged tiles (mcdn/skip.h), so
    // every band sees the whole frame's tile grid and makes the same skip decisions.
    const int grid = kConvergedTileSize;
    auto round_up = [grid](int64_t v) { return int((v + grid - 1) / grid * grid); };
    halo = round_up(halo);
    const int max_rows = std::max(grid, int(band_pixels / width) / grid * grid);
    int inner = height - 2 * halo;  // the rows bands own besides the ends' extra halo
    int nbands = std::max(2, (inner + max_rows - 1) / max_rows);
    int rows = inner > 0 ? round_up((inner + nbands - 1) / nbands) : 0;
    int first = rows + halo;
    if (inner <= 0 || first >= height) {
        nbands = (height + max_rows - 1) / max_rows;
        rows = first = round_up((height + nbands - 1) / nbands);
    }
    std::vector<Band> bands;
    for (int y0 = whole.ybegin; y0 < whole.yend;) {
        const int own = y0 == whole.ybegin ? first : rows;
        // The last band takes what is left: at most a halo more than the others.
        const int end =
            int(bands.size()) + 1 >= nbands ? whole.yend : std::min(whole.yend, y0 + own);
        Band band { whole, y0, end };
        band.cut.ybegin = std::max(whole.ybegin, y0 - halo);
        band.cut.yend = std::min(whole.yend, end + halo);
        bands.push_back(band);
        y0 = end;
    }
    return bands;
}

void write_rows(ImageBuf& frame, int channel, const Plane& band_plane, int band_y, ROI roi)
{
    const ImageSpec& spec = frame.spec();
    ROI rows(spec.x, spec.x + band_plane.width, band_y, band_y + band_plane.height, spec.z,
             spec.z + 1, channel, channel + 1);
    roi = OIIO::roi_intersection(roi.defined() ? roi : rows, rows);
    roi.chbegin = channel;
    roi.chend = channel + 1;
    if (roi.xend <= roi.xbegin || roi.yend <= roi.ybegin)
        return;
    // The plane's rows are contiguous: one set_pixels with the plane's strides.
    const float* first = band_plane.row(roi.ybegin - band_y) + (roi.xbegin - spec.x);
    frame.set_pixels(roi, OIIO::TypeDesc::FLOAT, first, sizeof(float),
                     OIIO::stride_t(band_plane.width * sizeof(float)));
}

void write_rows(ImageBuf& frame, const std::vector<int>& channels,
                const std::vector<const Plane*>& band_planes, int band_y, ROI roi)
{
    float* pixels = const_cast<float*>(float_frame_pixels(frame));
    if (!pixels || band_planes.empty()) {
        for (size_t p = 0; p < band_planes.size(); ++p)
            write_rows(frame, channels[p], *band_planes[p], band_y, roi);
        return;
    }
    const ImageSpec& spec = frame.spec();
    const Plane& first = *band_planes[0];
    ROI rows(spec.x, spec.x + first.width, band_y, band_y + first.height, spec.z, spec.z + 1);
    roi = OIIO::roi_intersection(roi.defined() ? roi : rows, rows);
    if (roi.xend <= roi.xbegin || roi.yend <= roi.ybegin)
        return;
    const int nch = spec.nchannels, n = int(band_planes.size());
    tbb::parallel_for(
        tbb::blocked_range<int>(roi.ybegin, roi.yend), [&](const tbb::blocked_range<int>& b) {
            for (int y = b.begin(); y != b.end(); ++y) {
                float* out =
                    pixels + (size_t(y - spec.y) * spec.width + size_t(roi.xbegin - spec.x)) * nch;
                for (int p = 0; p < n; ++p) {
                    const float* in = band_planes[p]->row(y - band_y) + (roi.xbegin - spec.x);
                    const int c = channels[p];
                    for (int x = 0; x < roi.width(); ++x)
                        out[size_t(x) * nch + c] = in[x];
                }
            }
        });
}

namespace {

// run_in_bands runs the op on the whole frame at once.
bool runs_whole(const ROI& whole, int64_t band_pixels)
{
    return band_pixels <= 0 || int64_t(whole.npixels()) <= band_pixels;
}

}  // namespace

int band_count(const ROI& whole, int halo, int64_t band_pixels)
{
    return runs_whole(whole, band_pixels) ? 1 : int(plan_bands(whole, halo, band_pixels).size());
}

bool run_in_bands(ImageBuf& dst, const ImageBuf& src, int halo, int64_t band_pixels,
                  const BandOp& op)
{
    const ROI whole = src.roi();
    const int64_t width = std::max<int64_t>(1, whole.width());
    const int height = whole.height();
    if (runs_whole(whole, band_pixels))
        return op(dst, src);
    ImageBuf out;
    for (const Band& planned : plan_bands(whole, halo, band_pixels)) {
        const int y0 = planned.own_begin, y1 = planned.own_end;
        const ROI& cut = planned.cut;
        ImageBuf band_out;
        {
            ImageBuf band = OIIO::ImageBufAlgo::copy(src, OIIO::TypeUnknown, cut);
            if (!op(band_out, band)) {
                dst.errorfmt("{}", band_out.geterror());
                return false;
            }
        }
        const ImageSpec& band_spec = band_out.spec();
        if (!out.initialized()) {
            ImageSpec spec = band_spec;
            spec.y = whole.ybegin;
            spec.height = height;
            out.reset(spec, OIIO::InitializePixels::No);
        }
        if (band_spec.format != OIIO::TypeFloat || !band_spec.channelformats.empty()
            || band_spec.nchannels != out.nchannels() || band_spec.width != whole.width()
            || band_spec.x != whole.xbegin || !band_out.localpixels()) {
            dst.errorfmt("bands: a band's result is not a float frame of the band's window");
            return false;
        }
        // The band's own rows, contiguous in both buffers (whole rows of all channels).
        const size_t row_floats = size_t(width) * size_t(out.nchannels());
        const float* from = static_cast<const float*>(band_out.localpixels())
                            + size_t(y0 - band_spec.y) * row_floats;
        float* to = static_cast<float*>(out.localpixels()) + size_t(y0 - whole.ybegin) * row_floats;
        std::memcpy(to, from, size_t(y1 - y0) * row_floats * sizeof(float));
    }
    dst = std::move(out);
    return true;
}

bool run_local_op(ImageBuf& dst, const ImageBuf& src, const AovSpec& aovs, const char* op_name,
                  int halo, int64_t band_pixels, const BandOp& op)
{
    return run_in_bands(dst, src, halo, band_pixels, [&](ImageBuf& band_dst, const ImageBuf& band) {
        return run_in_working_space(band_dst, band, aovs, op_name, op);
    });
}

}  // namespace mcdn
