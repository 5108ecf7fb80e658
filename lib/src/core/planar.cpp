#include "core/planar.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

namespace mcdn {

std::vector<Rect> make_tiles(int width, int height, int tile_size)
{
    std::vector<Rect> tiles;
    for (int y = 0; y < height; y += tile_size)
        for (int x = 0; x < width; x += tile_size)
            tiles.push_back(
                { x, y, std::min(x + tile_size, width), std::min(y + tile_size, height) });
    return tiles;
}

void parallel_for_index(int n, int nthreads, const std::function<void(int)>& body)
{
    if (n <= 0)
        return;
    if (nthreads == 1 || n == 1) {
        for (int i = 0; i < n; ++i)
            body(i);
        return;
    }
    tbb::task_arena arena(nthreads > 0 ? nthreads : tbb::task_arena::automatic);
    arena.execute([&] {
        tbb::parallel_for(
            tbb::blocked_range<int>(0, n, 1),
            [&](const tbb::blocked_range<int>& r) {
                for (int i = r.begin(); i != r.end(); ++i)
                    body(i);
            },
            tbb::simple_partitioner());
    });
}

void for_pixel_chunks(size_t npixels, int nthreads,
                      const std::function<void(size_t begin, size_t end)>& body)
{
    constexpr size_t kChunk = 16384;  // pixels: enough work per task, many tasks per thread
    const size_t chunks = (npixels + kChunk - 1) / kChunk;
    parallel_for_index(int(chunks), nthreads, [&](int i) {
        body(size_t(i) * kChunk, std::min(npixels, size_t(i + 1) * kChunk));
    });
}

namespace {

// Where pixel (x, y) of a float frame (float_frame_pixels) starts.
size_t pixel_index(const OIIO::ImageSpec& spec, int x, int y)
{
    return (size_t(y - spec.y) * size_t(spec.width) + size_t(x - spec.x)) * size_t(spec.nchannels);
}

// Whether `rows` lies inside the data window of `spec` (single plane z).
bool inside(const OIIO::ImageSpec& spec, const OIIO::ROI& rows)
{
    return rows.xbegin >= spec.x && rows.xend <= spec.x + spec.width && rows.ybegin >= spec.y
           && rows.yend <= spec.y + spec.height && spec.depth <= 1;
}

// Pixels of a row that one pass of read_planes and write_planes covers: all the channels of
// this many pixels stay in the cache while each plane takes its own.
constexpr int kPassPixels = 256;

// Rows [y0, y1) of `rows` of a float frame's channels into planes of the rows' size.
void read_frame_rows(const OIIO::ImageSpec& spec, const float* frame, const OIIO::ROI& rows,
                     const std::vector<PlaneRead>& reads, int y0, int y1)
{
    const size_t nch = size_t(spec.nchannels);
    for (int y = y0; y < y1; ++y)
        for (int x0 = rows.xbegin; x0 < rows.xend; x0 += kPassPixels) {
            const int n = std::min(kPassPixels, rows.xend - x0);
            const float* pixels = frame + pixel_index(spec, x0, y);
            for (const PlaneRead& r : reads) {
                const float* in = pixels + r.channel;
                float* out = r.out->row(y - rows.ybegin) + (x0 - rows.xbegin);
                if (r.is_variance)
                    for (int x = 0; x < n; ++x)
                        out[x] = sanitize_variance(in[size_t(x) * nch]);
                else
                    for (int x = 0; x < n; ++x)
                        out[x] = sanitize(in[size_t(x) * nch]);
            }
        }
}

// Rows of `roi` of planes (on the frame's data window) into a float frame's channels.
void write_frame_rows(const OIIO::ImageSpec& spec, float* frame, const OIIO::ROI& roi,
                      const std::vector<PlaneWrite>& writes)
{
    const size_t nch = size_t(spec.nchannels);
    for (int y = roi.ybegin; y < roi.yend; ++y)
        for (int x0 = roi.xbegin; x0 < roi.xend; x0 += kPassPixels) {
            const int n = std::min(kPassPixels, roi.xend - x0);
            float* pixels = frame + pixel_index(spec, x0, y);
            for (const PlaneWrite& w : writes) {
                const float* in = w.plane->row(y - spec.y) + (x0 - spec.x);
                float* out = pixels + w.channel;
                for (int x = 0; x < n; ++x)
                    out[size_t(x) * nch] = in[x];
            }
        }
}

}  // namespace

Plane read_rows(const OIIO::ImageBuf& src, int channel, const OIIO::ROI& rows, bool is_variance)
{
    Plane plane(rows.width(), rows.height());
    const OIIO::ImageSpec& spec = src.spec();
    // A float frame is read straight from its pixels: one strided pass, no iterator per pixel.
    if (const float* frame = float_frame_pixels(src); frame && inside(spec, rows)) {
        read_frame_rows(spec, frame, rows, { { channel, &plane, is_variance } }, rows.ybegin,
                        rows.yend);
        return plane;
    }
    OIIO::ROI one = rows;
    one.chbegin = channel;
    one.chend = channel + 1;
    src.get_pixels(one, OIIO::TypeDesc::FLOAT, plane.data());
    for (float& v : plane.px)
        v = is_variance ? sanitize_variance(v) : sanitize(v);
    return plane;
}

const float* float_frame_pixels(const OIIO::ImageBuf& frame)
{
    const OIIO::ImageSpec& spec = frame.spec();
    if (!frame.localpixels() || spec.format != OIIO::TypeDesc::FLOAT
        || frame.pixel_stride() != OIIO::stride_t(spec.pixel_bytes())
        || frame.scanline_stride() != OIIO::stride_t(spec.scanline_bytes()))
        return nullptr;
    return static_cast<const float*>(frame.localpixels());
}

Plane read_plane(const OIIO::ImageBuf& src, int channel, bool is_variance)
{
    const OIIO::ImageSpec& spec = src.spec();
    return read_rows(
        src, channel,
        OIIO::ROI(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height, spec.z, spec.z + 1),
        is_variance);
}

void write_plane(OIIO::ImageBuf& dst, int channel, const Plane& plane, OIIO::ROI roi)
{
    const OIIO::ImageSpec& spec = dst.spec();
    OIIO::ROI full(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height, spec.z, spec.z + 1,
                   channel, channel + 1);
    roi = OIIO::roi_intersection(roi.defined() ? roi : full, full);
    roi.chbegin = channel;
    roi.chend = channel + 1;
    if (roi.npixels() == 0)
        return;
    // A float frame is written straight into its pixels (no copy of the plane, no iterator).
    if (float_frame_pixels(dst) && inside(spec, roi)) {
        write_frame_rows(spec, static_cast<float*>(dst.localpixels()), roi,
                         { { channel, &plane } });
        return;
    }
    // Copy the ROI rows out of the plane, then hand them to OIIO in one call.
    std::vector<float> rows(size_t(roi.width()) * roi.height());
    for (int y = roi.ybegin; y < roi.yend; ++y)
        std::copy_n(plane.row(y - spec.y) + (roi.xbegin - spec.x), roi.width(),
                    rows.data() + size_t(y - roi.ybegin) * roi.width());
    dst.set_pixels(roi, OIIO::TypeDesc::FLOAT, rows.data());
}

void read_planes(const OIIO::ImageBuf& src, const std::vector<PlaneRead>& reads, OIIO::ROI rows,
                 int nthreads)
{
    const OIIO::ImageSpec& spec = src.spec();
    if (!rows.defined())
        rows = OIIO::ROI(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height, spec.z,
                         spec.z + 1);
    const float* frame = float_frame_pixels(src);
    if (!frame || !inside(spec, rows)) {
        for (const PlaneRead& r : reads)
            *r.out = read_rows(src, r.channel, rows, r.is_variance);
        return;
    }
    for (const PlaneRead& r : reads)
        *r.out = Plane(rows.width(), rows.height());
    constexpr int kRowsPerTask = 16;
    const int tasks = (rows.height() + kRowsPerTask - 1) / kRowsPerTask;
    parallel_for_index(tasks, nthreads, [&](int t) {
        const int y0 = rows.ybegin + t * kRowsPerTask;
        read_frame_rows(spec, frame, rows, reads, y0, std::min(y0 + kRowsPerTask, rows.yend));
    });
}

void write_planes(OIIO::ImageBuf& dst, const std::vector<PlaneWrite>& writes, OIIO::ROI roi)
{
    const OIIO::ImageSpec& spec = dst.spec();
    const OIIO::ROI full(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height, spec.z,
                         spec.z + 1);
    roi = OIIO::roi_intersection(roi.defined() ? roi : full, full);
    if (!float_frame_pixels(dst) || !inside(spec, roi)) {
        for (const PlaneWrite& w : writes)
            write_plane(dst, w.channel, *w.plane, roi);
        return;
    }
    write_frame_rows(spec, static_cast<float*>(dst.localpixels()), roi, writes);
}

}  // namespace mcdn
