// Planar float images and the deterministic tile loop shared by the NL-means stages
// (prefilter, nfor): one contiguous plane per channel, so that the pixel loops run along
// rows of one channel and vectorise.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

/// One channel of an image, row-major, origin at the data window's corner.
struct Plane {
    int width = 0, height = 0;
    std::vector<float> px;

    Plane() = default;
    Plane(int w, int h, float fill = 0.0f) : width(w), height(h), px(size_t(w) * h, fill) { }
    float* data() { return px.data(); }
    const float* data() const { return px.data(); }
    float* row(int y) { return px.data() + size_t(y) * width; }
    const float* row(int y) const { return px.data() + size_t(y) * width; }
    float& operator()(int x, int y) { return px[size_t(y) * width + x]; }
    float operator()(int x, int y) const { return px[size_t(y) * width + x]; }
    size_t size() const { return px.size(); }
};

/// A half-open pixel rectangle [x0, x1) x [y0, y1) in plane coordinates.
struct Rect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    int width() const { return x1 - x0; }
    int height() const { return y1 - y0; }
    bool empty() const { return x1 <= x0 || y1 <= y0; }
};

/// The tiles (row-major) covering a w x h plane.
std::vector<Rect> make_tiles(int width, int height, int tile_size);

/// Runs body(i) for i in [0, n) on `nthreads` threads (0 = all cores, 1 = this thread).
/// Each call must write only its own outputs: results never depend on the scheduling.
void parallel_for_index(int n, int nthreads, const std::function<void(int)>& body);

/// Runs body(begin, end) over [0, npixels) in chunks of consecutive pixels on `nthreads`
/// threads (parallel_for_index): for per-pixel work on an interleaved frame.
void for_pixel_chunks(size_t npixels, int nthreads,
                      const std::function<void(size_t begin, size_t end)>& body);

/// Largest magnitude an op lets into its arithmetic: squares and window sums of
/// (differences of) such values stay finite in float. validate_inputs refuses larger ones
/// (mcdn/io.h kHugeValue, the same number: io.cpp checks it).
constexpr float kMaxMagnitude = 1e15f;

/// Finite and clamped to +-kMaxMagnitude; NaN becomes `nan_value`.
inline float sanitize(float v, float nan_value = 0.0f)
{
    if (!(v == v))
        return nan_value;
    return std::min(std::max(v, -kMaxMagnitude), kMaxMagnitude);
}
/// A variance: NaN (no sample) and negative become 0, huge is clamped.
inline float sanitize_variance(float v)
{
    if (!(v > 0.0f))
        return 0.0f;
    return std::min(v, kMaxMagnitude);
}

/// The pixels of a float frame held contiguously in memory (all channels of a pixel, pixel
/// after pixel, row after row), or null: then read it through OIIO (read_plane, get_pixels).
const float* float_frame_pixels(const OIIO::ImageBuf& frame);

/// Reads channel `channel` of `src` (data window) into a plane, sanitized.
Plane read_plane(const OIIO::ImageBuf& src, int channel, bool is_variance = false);
/// The same for the rows `rows` of the data window only (a band, without copying the band):
/// a plane of the rows' size.
Plane read_rows(const OIIO::ImageBuf& src, int channel, const OIIO::ROI& rows,
                bool is_variance = false);
/// Writes a plane into channel `channel` of `dst` (same data window), inside `roi` only.
void write_plane(OIIO::ImageBuf& dst, int channel, const Plane& plane, OIIO::ROI roi);

/// One channel to read into a plane of its own, as read_plane does.
struct PlaneRead {
    int channel;
    Plane* out;
    bool is_variance = false;
};
/// Reads several channels of `src`'s rows `rows` (undefined: the data window) into planes
/// of the rows' size in one pass over its pixels, rows on `nthreads` threads: a pass per
/// channel pulls every cache line of an interleaved frame once per channel.
void read_planes(const OIIO::ImageBuf& src, const std::vector<PlaneRead>& reads,
                 OIIO::ROI rows = {}, int nthreads = 1);
/// One plane to write into a channel, as write_plane does.
struct PlaneWrite {
    int channel;
    const Plane* plane;
};
/// Writes several planes into `dst` inside `roi`, in one pass over its pixels.
void write_planes(OIIO::ImageBuf& dst, const std::vector<PlaneWrite>& writes, OIIO::ROI roi);

}  // namespace mcdn
