// KPCN's raw planes (Bako et al. 2017): the diffuse/specular split of §4.3 and the features,
// read on a rectangle of the frame (a network tile's window: nothing here is whole-frame but
// the depth range). training/cnn/data.py is the same computation in Python; the whole op is
// checked against it (tests/cnn/cnn_test.cpp). The network inputs: branch_inputs.cpp.
#include <algorithm>
#include <cmath>

#include <OpenImageIO/strutil.h>

#include "aov/transmission.h"
#include "cnn/cnn_steps.h"
#include "core/extra_aovs.h"

namespace mcdn {
namespace kpcn {

namespace {

/// Channels of src inside a rectangle of the frame, as read_plane reads them (sanitized).
/// A float frame in memory (the op's own copy) is read in place; any other image (in a file
/// cache, or half floats) is converted once, every channel of the window in one get_pixels:
/// get_pixels of a single channel copies a float at a time (slower than the whole KPCN
/// input step).
class WindowReader {
public:
    const Rect rect;

    /// `channels_at_once`: false for a reader of one or two channels (no whole-pixel copy).
    WindowReader(const ImageBuf& src, Rect rect, bool channels_at_once = true)
        : rect(rect), src_(src)
    {
        const ImageSpec& s = src.spec();
        if (src.localpixels() && s.format == OIIO::TypeDesc::FLOAT) {
            first_ = static_cast<const float*>(src.pixeladdr(s.x + rect.x0, s.y + rect.y0));
            pixel_step_ = size_t(src.pixel_stride()) / sizeof(float);
            row_step_ = size_t(src.scanline_stride()) / sizeof(float);
        } else if (channels_at_once) {
            block_.resize(size_t(rect.width()) * rect.height() * s.nchannels);
            src.get_pixels(ROI(s.x + rect.x0, s.x + rect.x1, s.y + rect.y0, s.y + rect.y1, s.z,
                               s.z + 1, 0, s.nchannels),
                           OIIO::TypeDesc::FLOAT, block_.data());
            first_ = block_.data();
            pixel_step_ = size_t(s.nchannels);
            row_step_ = pixel_step_ * rect.width();
        }
    }

    const ImageSpec& spec() const { return src_.spec(); }
    Plane blank(float fill = 0.0f) const { return Plane(rect.width(), rect.height(), fill); }
    Plane plane(int channel, bool is_variance = false) const
    {
        Plane plane = blank();
        if (first_) {
            for (int y = 0; y < rect.height(); ++y) {
                const float* in = first_ + y * row_step_ + channel;
                float* out = plane.row(y);
                for (int x = 0; x < rect.width(); ++x)
                    out[x] = in[x * pixel_step_];
            }
        } else {
            const ImageSpec& s = src_.spec();
            src_.get_pixels(ROI(s.x + rect.x0, s.x + rect.x1, s.y + rect.y0, s.y + rect.y1, s.z,
                                s.z + 1, channel, channel + 1),
                            OIIO::TypeDesc::FLOAT, plane.data());
        }
        for (float& v : plane.px)
            v = is_variance ? sanitize_variance(v) : sanitize(v);
        return plane;
    }

private:
    const ImageBuf& src_;
    std::vector<float> block_;  // the window's pixels, when src is not a float frame in memory
    const float* first_ = nullptr;
    size_t pixel_step_ = 0, row_step_ = 0;
};

/// Index of "variance.<channel name>", or -1.
int variance_channel(const WindowReader& src, int channel)
{
    const ImageSpec& spec = src.spec();
    return spec.channelindex(std::string(input_kind_prefix(InputKind::Variance))
                             + spec.channelnames[channel]);
}

/// The three channels named `names` (mean and, when `variance` is given, their variance
/// channels); false when any is missing.
bool read_pass(const WindowReader& src, const std::vector<std::string>& names, Plane mean[3],
               Plane* variance = nullptr)
{
    for (int c = 0; c < 3; ++c) {
        const int index = src.spec().channelindex(names[c]);
        if (index < 0)
            return false;
        const int v = variance ? variance_channel(src, index) : 0;
        if (v < 0)
            return false;
        mean[c] = src.plane(index);
        if (variance)
            variance[c] = src.plane(v, true);
    }
    return true;
}

/// Adds the value and delta-method variance of colour·(direct + indirect) to the sums:
/// Var[C (D + I)] ~ C² (Var D + Var I) + (D + I)² Var C. False when a pass or one of its
/// variances is missing (nothing is added then).
bool add_product(const WindowReader& src, const AovSet& aovs,
                 const std::vector<std::string> names[3], Plane value[3], Plane variance[3],
                 bool& variance_complete)
{
    // In the working space the light passes hold C·D and C·I already (mcdn/color.h
    // into_working_space), their variances C²·Var: the product is their sum.
    const bool light = extra_holds_light(src.spec(), aovs, names[1])
                       && extra_holds_light(src.spec(), aovs, names[2]);
    Plane mean[3][3], var[3][3];
    bool have_variance = true;
    for (int p = 0; p < 3; ++p) {
        if (have_variance && read_pass(src, names[p], mean[p], var[p]))
            continue;
        have_variance = false;  // the means alone
        if (!read_pass(src, names[p], mean[p]))
            return false;
    }
    variance_complete = variance_complete && have_variance;
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < value[c].size(); ++i) {
            const float color = mean[0][c].px[i];
            const float sum = mean[1][c].px[i] + mean[2][c].px[i];
            if (light) {
                value[c].px[i] += sum;
                const float passes = std::abs(color) > 1e-12f ? sum / color : 0.0f;
                if (have_variance)
                    variance[c].px[i] +=
                        var[1][c].px[i] + var[2][c].px[i] + passes * passes * var[0][c].px[i];
                continue;
            }
            value[c].px[i] += color * sum;
            if (have_variance)
                variance[c].px[i] += color * color * (var[1][c].px[i] + var[2][c].px[i])
                                     + sum * sum * var[0][c].px[i];
        }
    return true;
}

/// Mean and variance of a feature role; the variance from its variance role, else from the
/// half buffers ((A − B)² / 4 per pixel), else zero. Missing feature: zero planes.
void read_feature(const WindowReader& src, const AovSet& aovs, Role base, int channels, Plane* mean,
                  Plane* variance)
{
    const Role var_role = face_of(base, Face::Variance);
    const Role a_role = face_of(base, Face::HalfA), b_role = face_of(base, Face::HalfB);
    for (int c = 0; c < channels; ++c) {
        mean[c] = src.blank();
        variance[c] = src.blank();
        if (!aovs.has(base))
            continue;
        mean[c] = src.plane(aovs.channels(base)[c]);
        if (aovs.has(var_role)) {
            variance[c] = src.plane(aovs.channels(var_role)[c], true);
        } else if (aovs.has(a_role) && aovs.has(b_role)) {
            Plane a = src.plane(aovs.channels(a_role)[c]);
            Plane b = src.plane(aovs.channels(b_role)[c]);
            for (size_t i = 0; i < a.size(); ++i) {
                const float d = a.px[i] - b.px[i];
                variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
}

bool cycles_split(const AovSet& aovs)
{
    return aovs.has(Role::DiffuseColor) && aovs.has(Role::DiffuseDirect)
           && aovs.has(Role::DiffuseIndirect);
}

/// The albedo divided out of the diffuse: DiffCol with Blender's passes, the feature albedo
/// with the generic preset's diffuse, else 1.
void read_demod(const WindowReader& src, const AovSet& aovs, Plane demod[3])
{
    for (int c = 0; c < 3; ++c)
        demod[c] = src.blank(1.0f);
    if (cycles_split(aovs))
        read_pass(src, aovs.names(Role::DiffuseColor), demod);
    else if (aovs.has(Role::Diffuse) && aovs.has(Role::Albedo))
        for (int c = 0; c < 3; ++c)
            demod[c] = src.plane(aovs.channels(Role::Albedo)[c]);
}

Rect whole_frame(const ImageBuf& src)
{
    return { 0, 0, src.spec().width, src.spec().height };
}

}  // namespace

bool has_split(const AovSet& aovs)
{
    return cycles_split(aovs) || aovs.has(Role::Diffuse);
}

void read_demod(Plane demod[3], const ImageBuf& src, const AovSet& aovs, Rect rect)
{
    read_demod(WindowReader(src, rect), aovs, demod);
}

bool read_raw_planes(RawPlanes& raw, const ImageBuf& src, const AovSet& aovs, std::string& error,
                     Rect rect)
{
    const WindowReader reader(src, rect.empty() ? whole_frame(src) : rect);
    raw.rect = reader.rect;
    raw.frame_width = src.spec().width;
    raw.frame_height = src.spec().height;
    const auto& color = aovs.channels(Role::Color);
    for (int c = 0; c < 3; ++c) {
        raw.color[c] = reader.plane(color[c]);
        raw.color_var[c] = aovs.has(Role::ColorVariance)
                               ? reader.plane(aovs.channels(Role::ColorVariance)[c], true)
                               : reader.blank();
    }
    const int w = raw.width(), h = raw.height();
    for (int c = 0; c < 3; ++c) {
        raw.diffuse[c] = Plane(w, h);
        raw.diffuse_var[c] = Plane(w, h);
        raw.specular_var[c] = Plane(w, h);
    }
    read_demod(reader, aovs, raw.demod);
    bool diffuse_var_complete = true, specular_var_complete = true;

    if (cycles_split(aovs)) {
        // §4.3 with Blender's passes: diffuse = DiffCol (DiffDir + DiffInd).
        const std::vector<std::string> diffuse[3] = { aovs.names(Role::DiffuseColor),
                                                      aovs.names(Role::DiffuseDirect),
                                                      aovs.names(Role::DiffuseIndirect) };
        add_product(reader, aovs, diffuse, raw.diffuse, raw.diffuse_var, diffuse_var_complete);
        // Specular = Combined − diffuse: glossy and transmission products, emission,
        // environment. Only their variances are needed (the value is the difference).
        Plane unused[3] = { Plane(w, h), Plane(w, h), Plane(w, h) };
        if (aovs.has(Role::GlossyColor) && aovs.has(Role::GlossyDirect)
            && aovs.has(Role::GlossyIndirect)) {
            const std::vector<std::string> glossy[3] = { aovs.names(Role::GlossyColor),
                                                         aovs.names(Role::GlossyDirect),
                                                         aovs.names(Role::GlossyIndirect) };
            add_product(reader, aovs, glossy, unused, raw.specular_var, specular_var_complete);
        }
        // Cycles' transmission passes have no role; they sit beside DiffCol (aov/transmission.h).
        const std::vector<std::string> trans[3] = {
            transmission_channels(diffuse[0], kTransmissionPasses[0]),
            transmission_channels(diffuse[0], kTransmissionPasses[1]),
            transmission_channels(diffuse[0], kTransmissionPasses[2])
        };
        add_product(reader, aovs, trans, unused, raw.specular_var, specular_var_complete);
        for (Role added : { Role::Emission, Role::Environment }) {
            if (!aovs.has(added))
                continue;
            Plane mean[3], var[3];
            if (!read_pass(reader, aovs.names(added), mean, var)) {
                specular_var_complete = false;
                continue;
            }
            for (int c = 0; c < 3; ++c)
                for (size_t i = 0; i < var[c].size(); ++i)
                    raw.specular_var[c].px[i] += var[c].px[i];
        }
        raw.split = true;
    } else if (aovs.has(Role::Diffuse)) {
        // Generic preset: the diffuse component given, divided by the feature albedo.
        Plane mean[3], var[3];
        diffuse_var_complete = read_pass(reader, aovs.names(Role::Diffuse), mean, var);
        if (!diffuse_var_complete)
            read_pass(reader, aovs.names(Role::Diffuse), mean);
        for (int c = 0; c < 3; ++c) {
            raw.diffuse[c] = mean[c];
            if (diffuse_var_complete)
                raw.diffuse_var[c] = var[c];
        }
        specular_var_complete =
            aovs.has(Role::Specular) && read_pass(reader, aovs.names(Role::Specular), mean, var);
        if (specular_var_complete)
            for (int c = 0; c < 3; ++c)
                raw.specular_var[c] = var[c];
        raw.split = true;
    }
    for (int c = 0; c < 3; ++c) {
        // Variances the file does not give: the colour's (an over-estimate).
        if (!diffuse_var_complete)
            raw.diffuse_var[c] = raw.color_var[c];
        if (!specular_var_complete)
            raw.specular_var[c] = raw.color_var[c];
        raw.specular[c] = Plane(w, h);
        for (size_t i = 0; i < raw.specular[c].size(); ++i) {
            raw.diffuse_var[c].px[i] = sanitize_variance(raw.diffuse_var[c].px[i]);
            raw.specular_var[c].px[i] = sanitize_variance(raw.specular_var[c].px[i]);
            raw.diffuse[c].px[i] = sanitize(raw.diffuse[c].px[i]);
            raw.specular[c].px[i] = sanitize(raw.color[c].px[i] - raw.diffuse[c].px[i]);
        }
    }

    // Features (§5.1): albedo (DiffCol when there is no feature albedo), normal, depth.
    const Role albedo =
        aovs.has(Role::Albedo) || !aovs.has(Role::DiffuseColor) ? Role::Albedo : Role::DiffuseColor;
    if (albedo == Role::DiffuseColor) {
        for (int c = 0; c < 3; ++c) {
            raw.albedo[c] = raw.demod[c];
            raw.albedo_var[c] = Plane(w, h);
        }
    } else {
        read_feature(reader, aovs, albedo, 3, raw.albedo, raw.albedo_var);
    }
    read_feature(reader, aovs, Role::Normal, 3, raw.normal, raw.normal_var);
    read_feature(reader, aovs, Role::Depth, 1, &raw.depth, &raw.depth_var);
    error.clear();
    return true;
}

DepthRange depth_range(const Plane& depth)
{
    float lo = INFINITY, hi = -INFINITY;
    for (float d : depth.px) {
        lo = std::min(lo, d);
        hi = std::max(hi, d);
    }
    return { lo, hi - lo, hi };
}

DepthRange depth_range(const ImageBuf& src, const AovSet& aovs)
{
    if (!aovs.has(Role::Depth))
        return {};  // zero depth
    // Bands of rows: the range without a whole-frame plane (133 MB at 8K).
    constexpr int kBandRows = 64;
    const int channel = aovs.channels(Role::Depth)[0];
    float lo = INFINITY, hi = -INFINITY;
    for (int y = 0; y < src.spec().height; y += kBandRows) {
        const WindowReader band(
            src, { 0, y, src.spec().width, std::min(y + kBandRows, src.spec().height) }, false);
        const DepthRange r = depth_range(band.plane(channel));
        lo = std::min(lo, r.lo);
        hi = std::max(hi, r.hi);
    }
    return { lo, hi - lo, hi };
}

void drop_outliers(RawPlanes& raw, const DroppedOutliers& outliers)
{
    const Rect& r = raw.rect;
    const uint32_t width = uint32_t(raw.frame_width);
    // The outliers of the rows of raw.rect, those of its columns taken.
    auto k =
        std::lower_bound(outliers.pixels.begin(), outliers.pixels.end(), uint32_t(r.y0) * width);
    const auto end = std::lower_bound(k, outliers.pixels.end(), uint32_t(r.y1) * width);
    for (; k != end; ++k) {
        const int x = int(*k % width), y = int(*k / width);
        if (x < r.x0 || x >= r.x1)
            continue;
        const size_t n = size_t(k - outliers.pixels.begin());
        const size_t i = size_t(y - r.y0) * raw.width() + size_t(x - r.x0);
        for (int c = 0; c < 3; ++c) {
            const float s = outliers.scale[n][c];
            raw.color[c].px[i] = outliers.mean[n][c];
            raw.color_var[c].px[i] = outliers.variance[n][c];
            raw.diffuse[c].px[i] *= s;
            raw.diffuse_var[c].px[i] *= s * s;
            raw.specular[c].px[i] = sanitize(raw.color[c].px[i] - raw.diffuse[c].px[i]);
            raw.specular_var[c].px[i] *= s * s;
        }
    }
}

void scale_depth(RawPlanes& raw, const DepthRange& range)
{
    const float lo = range.lo, span = range.span;
    if (!(span > 0)) {
        std::fill(raw.depth.px.begin(), raw.depth.px.end(), 0.0f);
        std::fill(raw.depth_var.px.begin(), raw.depth_var.px.end(), 0.0f);
        return;
    }
    for (size_t i = 0; i < raw.depth.size(); ++i) {
        raw.depth.px[i] = (raw.depth.px[i] - lo) / span;
        raw.depth_var.px[i] = raw.depth_var.px[i] / (span * span);
    }
}

}  // namespace kpcn
}  // namespace mcdn
