// KPCN's network inputs (Bako et al. 2017 §5.1), computed per network tile: a tile's window
// needs its raw planes and one more column and row (the forward differences), so no
// whole-frame input exists (34 channels: ~280 MB at 1080p, 4.5 GB at 8K). A tile is made in
// strips of rows, each read and computed in cache on the engine's OpenMP workers (between
// two tiles' convolutions: work on another pool would share the cores with them spinning). Every
// value is the whole-frame computation's, bit for bit: the same per-pixel arithmetic, the depth
// scaled by the whole frame's range (scale_depth), and rows and columns past the frame
// (nn::run_tiled's extension to the alignment) copies of its last ones.
// training/cnn/model.py branch_inputs is the same computation in Python.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include "cnn/cnn_steps.h"
#include "cnn/extras_kernels.h"
#include "nn/ops.h"
#include "nn/parallel.h"

namespace mcdn {
namespace kpcn {

namespace {

constexpr int kPixelChannels = 14;  // the inputs of one pixel alone; 14-33 are gradients
constexpr int kGuides = 10;         // colour 3, albedo 3, normal 3, depth 1: their gradients
constexpr int kGuide[kGuides] = { 0, 1, 2, 4, 5, 6, 7, 8, 9, 10 };  // their channels

float finite_input(float v)
{
    if (!(v == v))
        return 0.0f;
    return std::min(std::max(v, -kInputLimit), kInputLimit);
}

float relu(float v)
{
    return v > 0 ? v : 0.0f;
}

/// Channels 0-13 of raw pixel i, unclamped (the gradients are taken before the clamp), and
/// the 3 values the branch's kernels filter. Colour in the network domain (0-2) and its
/// variance there (3): variances move by the Taylor rule of §5.1, Var h(X) ~ h'(mu)² Var X.
void pixel_inputs(const RawPlanes& raw, Branch branch, size_t i, float* f, float* image)
{
    float color_var_sum = 0;
    for (int c = 0; c < 3; ++c) {
        float color, variance;
        if (branch == Branch::diffuse) {
            const float demod = relu(raw.demod[c].px[i]) + kAlbedoEpsilon;
            const float irradiance = relu(raw.diffuse[c].px[i]) / demod;
            const float irradiance_var = raw.diffuse_var[c].px[i] / (demod * demod);
            color = std::log1p(irradiance);
            variance = irradiance_var / ((1 + irradiance) * (1 + irradiance));
            image[c] = irradiance;
        } else {
            const float specular = relu(raw.specular[c].px[i]);
            color = std::log1p(specular);
            variance = raw.specular_var[c].px[i] / ((1 + specular) * (1 + specular));
            image[c] = color;
        }
        f[c] = color;
        color_var_sum += variance;
    }
    f[3] = std::log1p(relu(color_var_sum / 3));
    float albedo_var = 0, normal_var = 0;
    for (int c = 0; c < 3; ++c) {
        f[4 + c] = std::log1p(relu(raw.albedo[c].px[i]));
        f[7 + c] = raw.normal[c].px[i];
        albedo_var += raw.albedo_var[c].px[i];
        normal_var += raw.normal_var[c].px[i];
    }
    f[10] = raw.depth.px[i];
    f[11] = std::log1p(relu(albedo_var / 3));
    f[12] = std::log1p(relu(normal_var / 3));
    f[13] = std::log1p(relu(raw.depth_var.px[i]));
}

/// Rows [first, last) of a tile's inputs (tensors shaped to the window; the image's
/// channels 0-2), from raw planes covering inputs_rect of those rows.
void strip_inputs(const RawPlanes& raw, Branch branch, const Rect& window, int first, int last,
                  nn::Tensor& features, nn::Tensor& image)
{
    const int frame_width = raw.frame_width, frame_height = raw.frame_height;
    const Rect rect = inputs_rect({ window.x0, window.y0 + first, window.x1, window.y0 + last },
                                  frame_width, frame_height);
    // The per-pixel channels of the strip's pixels first, each pixel once (the worker's
    // scratch, kept: no allocation per strip).
    static thread_local std::vector<float> own, own_image;
    const int rw = rect.width(), rh = rect.height();
    own.resize(size_t(rw) * rh * kPixelChannels);
    own_image.resize(size_t(rw) * rh * 3);
    for (int ly = 0; ly < rh; ++ly) {
        const size_t raw_row = size_t(rect.y0 + ly - raw.rect.y0) * raw.width();
        for (int lx = 0; lx < rw; ++lx) {
            const size_t i = size_t(ly) * rw + lx;
            pixel_inputs(raw, branch, raw_row + (rect.x0 + lx - raw.rect.x0),
                         &own[i * kPixelChannels], &own_image[i * 3]);
        }
    }
    // Those channels, forward differences (zero in the frame's last column and row),
    // everything clamped to +-kInputLimit; past the frame, its last row and column.
    for (int wy = first; wy < last; ++wy) {
        const int y = std::min(window.y0 + wy, frame_height - 1);
        for (int wx = 0; wx < features.width; ++wx) {
            const int x = std::min(window.x0 + wx, frame_width - 1);
            const size_t i = size_t(y - rect.y0) * rw + (x - rect.x0);
            const float* g = &own[i * kPixelChannels];
            float* f = features.pixel(wy, wx);
            std::copy_n(g, kPixelChannels, f);
            for (int k = 0; k < kGuides; ++k) {
                const int ch = kGuide[k];
                f[14 + k] = x + 1 < frame_width ? g[kPixelChannels + ch] - g[ch] : 0.0f;
                f[24 + k] =
                    y + 1 < frame_height ? g[size_t(rw) * kPixelChannels + ch] - g[ch] : 0.0f;
            }
            for (int k = 0; k < kInputChannels; ++k)
                f[k] = finite_input(f[k]);
            std::copy_n(&own_image[i * 3], 3, image.pixel(wy, wx));
        }
    }
}

/// Rows of a window in strips of kStripRows on the engine's threads (nn/parallel.h: the
/// workers that run the convolutions, already awake): strip(first, last) for each.
constexpr int kStripRows = 16;  // one more row read per strip: ~6%
template <class Strip> void for_strips(int rows, Strip strip)
{
    const int strips = (rows + kStripRows - 1) / kStripRows;
    nn::parallel_rows(strips,
                      [&](int s) { strip(s * kStripRows, std::min((s + 1) * kStripRows, rows)); });
}

}  // namespace

Rect inputs_rect(const Rect& window, int frame_width, int frame_height)
{
    // Past the frame (run_tiled's extension), the last row or column stands for the rest.
    return { std::min(window.x0, frame_width - 1), std::min(window.y0, frame_height - 1),
             std::min(window.x1 + 1, frame_width), std::min(window.y1 + 1, frame_height) };
}

bool tile_inputs(const ImageBuf& src, const AovSet& aovs, const DepthRange& depth,
                 const std::vector<ExtraPlanes>& extras, const Rect& window, BranchInputs* diffuse,
                 BranchInputs& specular, std::string& error, const DroppedOutliers* outliers)
{
    const int image_channels = extras.empty() ? 3 : 3 * (2 + int(extras.size()));
    for (BranchInputs* b : { diffuse, &specular })
        if (b) {
            nn::reshape(b->features(), window.y1 - window.y0, window.x1 - window.x0,
                        kInputChannels);
            nn::reshape(b->image(), b->features().height, b->features().width, image_channels);
        }
    // Each strip reads the AOVs once for both branches and computes in cache, on every thread.
    std::atomic<bool> read { true };
    for_strips(specular.features().height, [&](int first, int last) {
        const Rect rows { window.x0, window.y0 + first, window.x1, window.y0 + last };
        RawPlanes raw;
        std::string strip_error;
        if (!read_raw_planes(raw, src, aovs, strip_error,
                             inputs_rect(rows, src.spec().width, src.spec().height))) {
            read = false;
            return;
        }
        if (outliers)
            drop_outliers(raw, *outliers);
        scale_depth(raw, depth);
        for (Branch branch : { Branch::diffuse, Branch::specular }) {
            BranchInputs* b = branch == Branch::diffuse ? diffuse : &specular;
            if (!b)
                continue;
            strip_inputs(raw, branch, window, first, last, b->features(), b->image());
            if (!extras.empty())
                add_extra_parts(b->image(), raw, extras, branch, window, first, last);
        }
    });
    if (!read)
        error = "cannot read the AOVs of a tile";
    return read;
}

void branch_inputs(const RawPlanes& raw, Branch branch, const Rect& window, nn::Tensor& features,
                   nn::Tensor& image)
{
    nn::reshape(features, window.y1 - window.y0, window.x1 - window.x0, kInputChannels);
    nn::reshape(image, features.height, features.width, 3);
    for_strips(features.height, [&](int first, int last) {
        strip_inputs(raw, branch, window, first, last, features, image);
    });
}

void branch_inputs(const RawPlanes& raw, Branch branch, nn::Tensor& features, nn::Tensor& image)
{
    branch_inputs(raw, branch, { 0, 0, raw.frame_width, raw.frame_height }, features, image);
}

}  // namespace kpcn
}  // namespace mcdn
