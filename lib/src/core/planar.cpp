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
            tiles.push_back({ x, y, std::min(x + tile_size, width), std::min(y + tile_size, height) });
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
        tbb::parallel_for(tbb::blocked_range<int>(0, n, 1),
                          [&](const tbb::blocked_range<int>& r) {
                              for (int i = r.begin(); i != r.end(); ++i)
                                  body(i);
                          },
                          tbb::simple_partitioner());
    });
}

Plane read_rows(const OIIO::ImageBuf& src, int channel, const OIIO::ROI& rows, bool is_variance)
{
    Plane plane(rows.width(), rows.height());
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
    return read_rows(src, channel, OIIO::ROI(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height,
                                             spec.z, spec.z + 1), is_variance);
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
    // Copy the ROI rows out of the plane, then hand them to OIIO in one call.
    std::vector<float> rows(size_t(roi.width()) * roi.height());
    for (int y = roi.ybegin; y < roi.yend; ++y)
        std::copy_n(plane.row(y - spec.y) + (roi.xbegin - spec.x), roi.width(),
                    rows.data() + size_t(y - roi.ybegin) * roi.width());
    dst.set_pixels(roi, OIIO::TypeDesc::FLOAT, rows.data());
}

}  // namespace mcdn
