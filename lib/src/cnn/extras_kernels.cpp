#include "cnn/extras_kernels.h"

#include <algorithm>

namespace mcdn {
namespace kpcn {

namespace {

/// r = diffuse / colour in [0, 1] (0 without a split or where the colour is ~0).
float diffuse_fraction(const RawPlanes& raw, int c, size_t i)
{
    const float color = raw.color[c].px[i];
    if (!raw.split || !(std::abs(color) > 1e-12f))
        return 0.0f;
    return std::clamp(raw.diffuse[c].px[i] / color, 0.0f, 1.0f);
}

}  // namespace

void add_extra_parts(nn::Tensor& image, const RawPlanes& raw,
                     const std::vector<ExtraPlanes>& extras, Branch branch, const Rect& window,
                     int first, int last)
{
    for (int wy = first; wy < last; ++wy)
        for (int wx = 0; wx < image.width; ++wx) {
            // The frame pixel (past the frame: its last row and column, as run_tiled extends).
            const int y = std::min(window.y0 + wy, raw.frame_height - 1);
            const int x = std::min(window.x0 + wx, raw.frame_width - 1);
            const size_t i = size_t(y - raw.rect.y0) * raw.width() + (x - raw.rect.x0);
            const size_t frame_i = size_t(y) * raw.frame_width + x;
            float* o = image.pixel(wy, wx);
            for (int c = 0; c < 3; ++c) {
                const float r = diffuse_fraction(raw, c, i);
                const float share = branch == Branch::diffuse
                                        ? r / (std::max(raw.demod[c].px[i], 0.0f) + kAlbedoEpsilon)
                                        : 1.0f - r;
                o[3 + c] = share * raw.color[c].px[i];
                for (int e = 0; e < int(extras.size()); ++e)
                    o[6 + 3 * e + c] = share * extras[e].mean[c].px[frame_i];
            }
        }
}

void write_extras(OutputFrame& frame, Rect rect, const std::vector<ExtraPlanes>& extras,
                  const BranchResult* diffuse, const BranchResult& specular)
{
    // The extra's share of one branch's component at (x, y) (0 where the colour's filtered
    // part vanishes: there the component has nothing to share).
    auto share = [&](const BranchResult& b, int e, int c, int x, int y) {
        const float* f = b.filtered->pixel(y - b.window_y0, x - b.window_x0);
        const float whole = f[3 + c];
        return std::abs(whole) > 1e-12f
                   ? b.component[c](x - rect.x0, y - rect.y0) * (f[6 + 3 * e + c] / whole)
                   : 0.0f;
    };
    for (int y = rect.y0; y < rect.y1; ++y)
        for (int x = rect.x0; x < rect.x1; ++x) {
            float* out = frame.pixel(x, y);
            for (int e = 0; e < int(extras.size()); ++e)
                for (int c = 0; c < 3; ++c) {
                    float v = share(specular, e, c, x, y);
                    if (diffuse)
                        v += share(*diffuse, e, c, x, y);
                    out[extras[e].channels[c]] = sanitize(v);
                }
        }
}

}  // namespace kpcn
}  // namespace mcdn
