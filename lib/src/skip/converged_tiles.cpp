// The converged-tile map (core/converged_tiles.h, mcdn/skip.h).
#include "skip/converged_tiles.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <OpenImageIO/strutil.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mcdn/metrics.h"

namespace mcdn {

namespace {
constexpr int T = kConvergedTileSize;
}  // namespace

bool ConvergedTiles::any() const
{
    return std::find(converged.begin(), converged.end(), 1) != converged.end();
}

int ConvergedTiles::count() const
{
    return int(std::count(converged.begin(), converged.end(), 1));
}

bool ConvergedTiles::covers(Rect r) const
{
    if (converged.empty())
        return false;
    r = { std::max(r.x0, 0), std::max(r.y0, 0), std::min(r.x1, width), std::min(r.y1, height) };
    if (r.empty())
        return false;
    for (int ty = r.y0 / T; ty <= (r.y1 - 1) / T; ++ty)
        for (int tx = r.x0 / T; tx <= (r.x1 - 1) / T; ++tx)
            if (!tile(tx, ty))
                return false;
    return true;
}

namespace {

/// A pixel's relative variance Var[mean] / (mean² + 0.01): its expected relMSE as rendered.
/// NaN stays NaN (never converged).
inline float relative_variance(float mean, float variance)
{
    return std::max(variance, 0.0f) / (mean * mean + float(kRelMseOffset));
}

}  // namespace

ConvergedTiles empty_tile_map(int width, int height)
{
    ConvergedTiles m;
    m.width = width;
    m.height = height;
    m.tiles_x = (width + T - 1) / T;
    m.tiles_y = (height + T - 1) / T;
    return m;
}

float relative_standard_error(float mean, float variance_of_mean)
{
    return std::sqrt(relative_variance(mean, variance_of_mean));
}

namespace {

/// The map of a width × height image, at(c, x, y) = {mean, variance} (mcdn/skip.h): a tile is
/// converged when at every pixel and channel the relative variance averaged over the pixel's
/// 3×3 neighbourhood within the tile is at most max_relative_error², and the pixel's own at
/// most (kOutlierFactor · max_relative_error)²: a tile is decided by its own pixels alone.
/// Threaded over rows of tiles, each decided by one thread: the map does not depend on the
/// thread count.
template <class At>
ConvergedTiles scan_converged(int width, int height, float max_relative_error, At at)
{
    ConvergedTiles m = empty_tile_map(width, height);
    const float limit = max_relative_error * max_relative_error;
    const float cap = kOutlierFactor * kOutlierFactor * limit;
    if (!(limit > 0) || m.width <= 0 || m.height <= 0)
        return m;
    m.converged.assign(size_t(m.tiles_x) * m.tiles_y, 1);
    const int w = m.width;
    tbb::parallel_for(
        tbb::blocked_range<int>(0, m.tiles_y), [&](const tbb::blocked_range<int>& rows) {
            std::vector<float> r, across;
            for (int ty = rows.begin(); ty != rows.end(); ++ty) {
                const int y0 = ty * T, y1 = std::min(y0 + T, m.height);
                // The tile row's relative variances, pixel-major, and their sums over x-1..x+1
                // within each tile.
                r.resize(size_t(y1 - y0) * w * 3);
                across.resize(r.size());
                for (int y = y0; y < y1; ++y) {
                    float* row = r.data() + size_t(y - y0) * w * 3;
                    for (int x = 0; x < w; ++x)
                        for (int c = 0; c < 3; ++c) {
                            const auto [mu, var] = at(c, x, y);
                            row[size_t(x) * 3 + c] = relative_variance(mu, var);
                        }
                    float* sum = across.data() + size_t(y - y0) * w * 3;
                    for (int x = 0; x < w; ++x) {
                        const int tile_x0 = x / T * T, tile_x1 = std::min(tile_x0 + T, w);
                        for (int c = 0; c < 3; ++c) {
                            float s = row[size_t(x) * 3 + c];
                            if (x > tile_x0)
                                s += row[size_t(x - 1) * 3 + c];
                            if (x + 1 < tile_x1)
                                s += row[size_t(x + 1) * 3 + c];
                            sum[size_t(x) * 3 + c] = s;
                        }
                    }
                }
                for (int y = y0; y < y1; ++y) {
                    const int ya = std::max(y - 1, y0), yb = std::min(y + 1, y1 - 1);
                    for (int x = 0; x < w; ++x) {
                        uint8_t& tile = m.converged[size_t(ty) * m.tiles_x + x / T];
                        if (!tile)
                            continue;
                        const int tile_x0 = x / T * T, tile_x1 = std::min(tile_x0 + T, w);
                        const int nx = std::min(x + 1, tile_x1 - 1) - std::max(x - 1, tile_x0) + 1;
                        const float count = float(nx * (yb - ya + 1));
                        for (int c = 0; c < 3; ++c) {
                            float s = 0;
                            for (int yy = ya; yy <= yb; ++yy)
                                s += across[(size_t(yy - y0) * w + x) * 3 + c];
                            const float own = r[(size_t(y - y0) * w + x) * 3 + c];
                            if (!(own <= cap) || !(s <= limit * count))
                                tile = 0;
                        }
                    }
                }
            }
        });
    if (!m.any())
        m.converged.clear();
    return m;
}

}  // namespace

ConvergedTiles find_converged_tiles(const Plane mean[3], const Plane variance[3],
                                    float max_relative_error)
{
    return scan_converged(mean[0].width, mean[0].height, max_relative_error,
                          [&](int c, int x, int y) {
                              return std::pair<float, float>(mean[c](x, y), variance[c](x, y));
                          });
}

bool attached_tiles(ConvergedTiles& m, const ImageBuf& src, const char* attribute, int width,
                    int height)
{
    const std::string attached = src.spec().get_string_attribute(attribute);
    return !attached.empty() && decode_converged_tiles(m, attached, width, height);
}

ConvergedTiles converged_tiles_of(const ImageBuf& src, const Plane mean[3], const Plane variance[3],
                                  const SkipOptions& skip)
{
    ConvergedTiles m;
    if (!skip.enabled || attached_tiles(m, src, kConvergedAttribute, mean[0].width, mean[0].height))
        return m;
    return find_converged_tiles(mean, variance, skip.max_relative_error);
}

ConvergedTiles converged_tiles_of(const ImageBuf& src, const AovSet& aovs, const SkipOptions& skip)
{
    if (!skip.enabled || !aovs.has(Role::Color) || !aovs.has(Role::ColorVariance)
        || aovs.channels(Role::Color).size() != 3 || aovs.channels(Role::ColorVariance).size() != 3)
        return {};
    const std::vector<int>& color = aovs.channels(Role::Color);
    const std::vector<int>& color_variance = aovs.channels(Role::ColorVariance);
    const ImageSpec& spec = src.spec();
    if (const float* pixels = float_frame_pixels(src)) {
        // A float frame in memory: one pass over its pixels, sanitized as read_plane does.
        // (Six planes would be six strided passes over a many-channel frame, and fresh
        // memory to fault in.)
        ConvergedTiles m;
        if (attached_tiles(m, src, kConvergedAttribute, spec.width, spec.height))
            return m;
        const size_t nchannels = size_t(spec.nchannels);
        return scan_converged(
            spec.width, spec.height, skip.max_relative_error, [&](int c, int x, int y) {
                const float* px = pixels + (size_t(y) * spec.width + x) * nchannels;
                return std::pair<float, float>(sanitize(px[color[c]]),
                                               sanitize_variance(px[color_variance[c]]));
            });
    }
    Plane mean[3], variance[3];
    for (int c = 0; c < 3; ++c) {
        mean[c] = read_plane(src, color[c]);
        variance[c] = read_plane(src, color_variance[c], true);
    }
    return converged_tiles_of(src, mean, variance, skip);
}

ConvergedCount count_converged_tiles(const ImageBuf& src, const AovSet& aovs,
                                     const SkipOptions& skip)
{
    const ImageSpec& spec = src.spec();
    ConvergedCount count;
    count.tiles = ((spec.width + T - 1) / T) * ((spec.height + T - 1) / T);
    count.converged = converged_tiles_of(src, aovs, skip).count();
    return count;
}

ConvergedTiles tiles_where_equal(const Plane a[3], const Plane b[3], const ConvergedTiles* within)
{
    ConvergedTiles m = empty_tile_map(a[0].width, a[0].height);
    m.converged.assign(size_t(m.tiles_x) * m.tiles_y, 0);
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx) {
            if (within && !within->tile(tx, ty))
                continue;
            bool same = true;
            for (int c = 0; c < 3 && same; ++c)
                for (int y = ty * T; y < std::min(ty * T + T, m.height) && same; ++y)
                    same = std::equal(a[c].row(y) + tx * T,
                                      a[c].row(y) + std::min(tx * T + T, m.width),
                                      b[c].row(y) + tx * T);
            m.converged[size_t(ty) * m.tiles_x + tx] = same;
        }
    if (!m.any())
        m.converged.clear();
    return m;
}

std::string encode_converged_tiles(const ConvergedTiles& m)
{
    std::string text = OIIO::Strutil::fmt::format("{}x{}:", m.width, m.height);
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx)
            text += m.tile(tx, ty) ? '1' : '0';
    return text;
}

bool decode_converged_tiles(ConvergedTiles& m, const std::string& text, int width, int height)
{
    const std::string head = OIIO::Strutil::fmt::format("{}x{}:", width, height);
    const int tiles_x = (width + T - 1) / T, tiles_y = (height + T - 1) / T;
    if (text.compare(0, head.size(), head) != 0
        || text.size() != head.size() + size_t(tiles_x) * tiles_y)
        return false;
    m = ConvergedTiles();
    m.width = width;
    m.height = height;
    m.tiles_x = tiles_x;
    m.tiles_y = tiles_y;
    m.converged.resize(size_t(tiles_x) * tiles_y);
    for (size_t i = 0; i < m.converged.size(); ++i)
        m.converged[i] = text[head.size() + i] == '1';
    if (!m.any())
        m.converged.clear();
    return true;
}

void pass_through_converged(Plane& out, const Plane& render, const ConvergedTiles& m)
{
    if (!m.any())
        return;
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx) {
            if (!m.tile(tx, ty))
                continue;
            const int x0 = tx * T, x1 = std::min(x0 + T, m.width);
            for (int y = ty * T; y < std::min(ty * T + T, m.height); ++y)
                std::copy(render.row(y) + x0, render.row(y) + x1, out.row(y) + x0);
        }
}

Plane tile_flags(const ConvergedTiles& m, int width, int height)
{
    Plane flags(width, height);
    pass_through_converged(flags, Plane(width, height, 1.0f), m);
    return flags;
}

std::vector<Rect> unconverged_rects(const ConvergedTiles& m, int max_side, int alignment)
{
    std::vector<Rect> rects;
    if (m.width <= 0 || m.height <= 0)
        return rects;
    // Runs of non-converged tiles per tile row, in tile units.
    struct Run {
        int tx0, tx1, ty0, ty1;
    };
    std::vector<Run> open, done;
    for (int ty = 0; ty < m.tiles_y; ++ty) {
        std::vector<Run> row;
        for (int tx = 0; tx < m.tiles_x;) {
            if (m.tile(tx, ty)) {
                ++tx;
                continue;
            }
            int end = tx;
            while (end < m.tiles_x && !m.tile(end, ty))
                ++end;
            row.push_back({ tx, end, ty, ty + 1 });
            tx = end;
        }
        // A run identical to one of the row above extends it downwards.
        std::vector<Run> next;
        for (Run r : row) {
            auto same = std::find_if(open.begin(), open.end(), [&](const Run& o) {
                return o.tx0 == r.tx0 && o.tx1 == r.tx1;
            });
            if (same != open.end()) {
                r.ty0 = same->ty0;
                open.erase(same);
            }
            next.push_back(r);
        }
        done.insert(done.end(), open.begin(), open.end());
        open = std::move(next);
    }
    done.insert(done.end(), open.begin(), open.end());
    std::sort(done.begin(), done.end(), [](const Run& a, const Run& b) {
        return a.ty0 != b.ty0 ? a.ty0 < b.ty0 : a.tx0 < b.tx0;
    });
    // In pixels, split into pieces of at most max_side (a multiple of the alignment).
    const int side = std::max(max_side / alignment, 1) * alignment;
    for (const Run& r : done) {
        const int x0 = r.tx0 * T, x1 = std::min(r.tx1 * T, m.width);
        const int y0 = r.ty0 * T, y1 = std::min(r.ty1 * T, m.height);
        for (int y = y0; y < y1; y += side)
            for (int x = x0; x < x1; x += side)
                rects.push_back({ x, y, std::min(x + side, x1), std::min(y + side, y1) });
    }
    return rects;
}

void pass_through_extras(ImageBuf& dst, ROI roi, const std::vector<ExtraPlanes>& extras,
                         const ConvergedTiles& m)
{
    if (!m.any())
        return;
    for (const ExtraPlanes& e : extras)
        for (int c = 0; c < 3; ++c) {
            Plane plane = read_plane(dst, e.channels[c]);
            pass_through_converged(plane, e.mean[c], m);
            write_plane(dst, e.channels[c], plane, roi);
        }
}

}  // namespace mcdn
