// The half buffers belong to the render (mcdn/io.h check_halves): NFOR (§5) regresses each
// half on the other's features and averages them, so halves of another frame, mirrored or
// holding a corrupt block would come out as the result whatever the render says.
#include <algorithm>
#include <cmath>
#include <vector>

#include <OpenImageIO/strutil.h>

#include "core/planar.h"
#include "mcdn/io.h"
#include "mcdn/skip.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;

namespace {

// What the halves' mean may differ from the render by beyond its noise: float and half
// rounding and a lossy codec (DWAA keeps about 1%) of the three files, relative to their
// values.
constexpr float kRounding = 0.01f;
// A tile fails where sum d^2 > kTileRatio * sum v over it: halves of the render give about
// 0 (the render is their mean), an independent render of the same scene about 2 (its noise
// and the render's). The frame (or band) fails where most of its tiles do: halves of
// another render or mirrored, not a corrupt block (which dominates any sum over the frame).
constexpr double kTileRatio = 0.5;
// A pixel fails where d^2 > kPixelRatio * max(v, e^2): a render whose halves hold unequal
// sample counts n_A != n_B has d^2 = ((n_A - n_B) / N)^2 e^2, under a quarter of e^2 up to
// a 75/25 split.
constexpr float kPixelRatio = 0.25f;

}  // namespace

bool check_halves(ImageBuf& merged, const AovSet& aovs,
                  std::vector<std::pair<int, int>>& repaired_tiles, std::string& error)
{
    repaired_tiles.clear();
    const std::vector<int>& mean = aovs.channels(Role::Color);
    const std::vector<int>& a = aovs.channels(Role::ColorA);
    const std::vector<int>& b = aovs.channels(Role::ColorB);
    const std::vector<int>& var = aovs.channels(Role::ColorVariance);
    if (mean.empty() || a.empty() || b.empty())
        return true;
    const ImageSpec& spec = merged.spec();
    float* pixels = static_cast<float*>(merged.localpixels());
    if (!pixels || spec.format != OIIO::TypeDesc::FLOAT) {
        error = "check_halves: expects a local float buffer (use read_inputs)";
        return false;
    }
    const int nch = spec.nchannels, width = spec.width, height = spec.height;
    const int tile = kConvergedTileSize;
    const int tiles_x = (width + tile - 1) / tile, tiles_y = (height + tile - 1) / tile;
    // Per tile: sums of d^2 and of v, and whether a pixel fails (rows of tiles in parallel,
    // each writing its own: any thread count gives the same answer).
    const size_t ntiles = size_t(tiles_x) * tiles_y;
    std::vector<double> tile_d(ntiles, 0.0), tile_v(ntiles, 0.0);
    std::vector<char> bad(ntiles, 0);
    parallel_for_index(tiles_y, 0, [&](int ty) {
        for (int y = ty * tile; y < std::min(height, (ty + 1) * tile); ++y)
            for (int x = 0; x < width; ++x) {
                const float* p = pixels + (size_t(y) * width + x) * nch;
                for (size_t c = 0; c < mean.size(); ++c) {
                    const float m = p[mean[c]], pa = p[a[c]], pb = p[b[c]];
                    const float d = 0.5f * (pa + pb) - m, e = 0.5f * (pa - pb);
                    const float t = kRounding * (std::fabs(m) + std::fabs(pa) + std::fabs(pb));
                    const float v = var.empty() ? e * e : sanitize_variance(p[var[c]]);
                    const size_t k = size_t(ty) * tiles_x + x / tile;
                    tile_d[k] += double(d) * d;
                    tile_v[k] += double(v) + double(t) * t;
                    if (double(d) * d > kPixelRatio * (std::max(v, e * e) + t * t + 1e-30f))
                        bad[k] = 1;
                }
            }
    });
    size_t failed = 0;
    double worst = 0.0;
    for (size_t k = 0; k < ntiles; ++k) {
        const double ratio = tile_d[k] / std::max(tile_v[k], 1e-30);
        if (ratio > kTileRatio) {
            bad[k] = 1;
            ++failed;
        }
        worst = std::max(worst, ratio);
    }
    if (2 * failed > ntiles) {
        std::vector<std::string> files;
        for (const InputFile& f : merged_input_files(spec))
            if (f.kind == InputKind::HalfA || f.kind == InputKind::HalfB)
                files.push_back(f.path);
        const std::string halves =
            files.empty() ? std::string("the half buffers") : OIIO::Strutil::join(files, " and ");
        error =
            format("{}: the halves' mean is not the render: in {} of {} tiles of rows "
                   "{}-{} the colour ('{}', ...) differs from (A+B)/2 by more than {} "
                   "times its {} (up to {:.3g}; halves of this render give 0): give the "
                   "half buffers of this render",
                   halves, failed, ntiles, spec.y, spec.y + height - 1, spec.channelnames[mean[0]],
                   kTileRatio, var.empty() ? "noise ((A-B)/2)^2" : "variance", worst);
        return false;
    }
    // The tiles that fail: their halves become the render (A = B = the mean), so that no
    // stage takes the halves' pixels for the image there.
    for (int ty = 0; ty < tiles_y; ++ty)
        for (int tx = 0; tx < tiles_x; ++tx) {
            if (!bad[size_t(ty) * tiles_x + tx])
                continue;
            repaired_tiles.emplace_back(spec.x + tx * tile, spec.y + ty * tile);
            for (int y = ty * tile; y < std::min(height, (ty + 1) * tile); ++y)
                for (int x = tx * tile; x < std::min(width, (tx + 1) * tile); ++x) {
                    float* p = pixels + (size_t(y) * width + x) * nch;
                    for (size_t c = 0; c < mean.size(); ++c)
                        p[a[c]] = p[b[c]] = p[mean[c]];
                }
        }
    return true;
}

bool InputChecks::check(ImageBuf& rows, const AovSet& aovs, std::string& error)
{
    std::vector<std::pair<int, int>> repaired;
    if (!validate_inputs(rows, aovs, error) || !check_halves(rows, aovs, repaired, error))
        return false;
    m_repaired.insert(repaired.begin(), repaired.end());
    return true;
}

}  // namespace mcdn
