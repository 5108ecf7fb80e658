// KPCN inputs (Bako et al. 2017): the diffuse/specular split of §4.3 and the network input
// channels of §5.1. training/cnn/data.py and model.py are the same computations in Python;
// tests/cnn/pytorch_test.cpp checks the whole op against them.
#include <algorithm>
#include <cmath>

#include <OpenImageIO/strutil.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cnn/cnn_steps.h"
#include "nn/ops.h"

namespace mcdn {
namespace kpcn {

namespace {

/// Index of "variance.<channel name>", or -1.
int variance_channel(const ImageBuf& src, int channel)
{
    const ImageSpec& spec = src.spec();
    return spec.channelindex(std::string(input_kind_prefix(InputKind::Variance))
                             + spec.channelnames[channel]);
}

/// The three channels named `names` (mean and, when `variance` is given, their variance
/// channels); false when any is missing.
bool read_pass(const ImageBuf& src, const std::vector<std::string>& names, Plane mean[3],
               Plane* variance = nullptr)
{
    for (int c = 0; c < 3; ++c) {
        const int index = src.spec().channelindex(names[c]);
        if (index < 0)
            return false;
        const int v = variance ? variance_channel(src, index) : 0;
        if (v < 0)
            return false;
        mean[c] = read_plane(src, index);
        if (variance)
            variance[c] = read_plane(src, v, true);
    }
    return true;
}

std::vector<std::string> renamed(const std::vector<std::string>& names, const std::string& from,
                                 const std::string& to)
{
    std::vector<std::string> out;
    for (const auto& n : names)
        out.push_back(OIIO::Strutil::replace(n, from, to));
    return out;
}

/// Adds the value and delta-method variance of colour·(direct + indirect) to the sums:
/// Var[C (D + I)] ~ C² (Var D + Var I) + (D + I)² Var C. False when a pass or one of its
/// variances is missing (nothing is added then).
bool add_product(const ImageBuf& src, const std::vector<std::string> names[3], Plane value[3],
                 Plane variance[3], bool& variance_complete)
{
    Plane mean[3][3], var[3][3];
    for (int p = 0; p < 3; ++p)
        if (!read_pass(src, names[p], mean[p]))
            return false;
    bool have_variance = true;
    for (int p = 0; p < 3 && have_variance; ++p)
        have_variance = read_pass(src, names[p], mean[p], var[p]);
    variance_complete = variance_complete && have_variance;
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < value[c].size(); ++i) {
            const float colour = mean[0][c].px[i];
            const float light = mean[1][c].px[i] + mean[2][c].px[i];
            value[c].px[i] += colour * light;
            if (have_variance)
                variance[c].px[i] += colour * colour * (var[1][c].px[i] + var[2][c].px[i])
                                     + light * light * var[0][c].px[i];
        }
    return true;
}

/// Mean and variance of a feature role; the variance from its variance role, else from the
/// half buffers ((A − B)² / 4 per pixel), else zero. Missing feature: zero planes.
void read_feature(const ImageBuf& src, const AovSet& aovs, Role base, int channels, Plane* mean,
                  Plane* variance, int width, int height)
{
    const Role var_role = face_of(base, Face::Variance);
    const Role a_role = face_of(base, Face::HalfA), b_role = face_of(base, Face::HalfB);
    for (int c = 0; c < channels; ++c) {
        mean[c] = Plane(width, height);
        variance[c] = Plane(width, height);
        if (!aovs.has(base))
            continue;
        mean[c] = read_plane(src, aovs.channels(base)[c]);
        if (aovs.has(var_role)) {
            variance[c] = read_plane(src, aovs.channels(var_role)[c], true);
        } else if (aovs.has(a_role) && aovs.has(b_role)) {
            Plane a = read_plane(src, aovs.channels(a_role)[c]);
            Plane b = read_plane(src, aovs.channels(b_role)[c]);
            for (size_t i = 0; i < a.size(); ++i) {
                const float d = a.px[i] - b.px[i];
                variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
}

}  // namespace

bool read_raw_planes(RawPlanes& raw, const ImageBuf& src, const AovSet& aovs, std::string& error)
{
    const auto& colour = aovs.channels(Role::Color);
    for (int c = 0; c < 3; ++c) {
        raw.color[c] = read_plane(src, colour[c]);
        raw.color_var[c] = aovs.has(Role::ColorVariance)
                               ? read_plane(src, aovs.channels(Role::ColorVariance)[c], true)
                               : Plane(raw.color[c].width, raw.color[c].height);
    }
    const int w = raw.width(), h = raw.height();
    for (int c = 0; c < 3; ++c) {
        raw.diffuse[c] = Plane(w, h);
        raw.diffuse_var[c] = Plane(w, h);
        raw.specular_var[c] = Plane(w, h);
        raw.demod[c] = Plane(w, h, 1.0f);
    }
    bool diffuse_var_complete = true, specular_var_complete = true;

    const bool cycles_split = aovs.has(Role::DiffuseColor) && aovs.has(Role::DiffuseDirect)
                              && aovs.has(Role::DiffuseIndirect);
    if (cycles_split) {
        // §4.3 with Blender's passes: diffuse = DiffCol (DiffDir + DiffInd).
        const std::vector<std::string> diffuse[3] = { aovs.names(Role::DiffuseColor),
                                                      aovs.names(Role::DiffuseDirect),
                                                      aovs.names(Role::DiffuseIndirect) };
        add_product(src, diffuse, raw.diffuse, raw.diffuse_var, diffuse_var_complete);
        read_pass(src, diffuse[0], raw.demod);
        // Specular = Combined − diffuse: glossy and transmission products, emission,
        // environment. Only their variances are needed (the value is the difference).
        Plane unused[3] = { Plane(w, h), Plane(w, h), Plane(w, h) };
        if (aovs.has(Role::GlossyColor) && aovs.has(Role::GlossyDirect)
            && aovs.has(Role::GlossyIndirect)) {
            const std::vector<std::string> glossy[3] = { aovs.names(Role::GlossyColor),
                                                         aovs.names(Role::GlossyDirect),
                                                         aovs.names(Role::GlossyIndirect) };
            add_product(src, glossy, unused, raw.specular_var, specular_var_complete);
        }
        // Cycles' transmission passes have no role; they sit beside DiffCol in the same layer.
        const auto& diffcol = diffuse[0];
        const std::vector<std::string> trans[3] = { renamed(diffcol, "DiffCol", "TransCol"),
                                                    renamed(diffcol, "DiffCol", "TransDir"),
                                                    renamed(diffcol, "DiffCol", "TransInd") };
        add_product(src, trans, unused, raw.specular_var, specular_var_complete);
        for (Role added : { Role::Emission, Role::Environment }) {
            if (!aovs.has(added))
                continue;
            Plane mean[3], var[3];
            if (!read_pass(src, aovs.names(added), mean, var)) {
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
        diffuse_var_complete = read_pass(src, aovs.names(Role::Diffuse), mean, var);
        if (!diffuse_var_complete)
            read_pass(src, aovs.names(Role::Diffuse), mean);
        for (int c = 0; c < 3; ++c) {
            raw.diffuse[c] = mean[c];
            if (diffuse_var_complete)
                raw.diffuse_var[c] = var[c];
            if (aovs.has(Role::Albedo))
                raw.demod[c] = read_plane(src, aovs.channels(Role::Albedo)[c]);
        }
        specular_var_complete = aovs.has(Role::Specular)
                                && read_pass(src, aovs.names(Role::Specular), mean, var);
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
    const Role albedo = aovs.has(Role::Albedo) || !aovs.has(Role::DiffuseColor) ? Role::Albedo
                                                                                 : Role::DiffuseColor;
    if (albedo == Role::DiffuseColor) {
        for (int c = 0; c < 3; ++c) {
            raw.albedo[c] = raw.demod[c];
            raw.albedo_var[c] = Plane(w, h);
        }
    } else {
        read_feature(src, aovs, albedo, 3, raw.albedo, raw.albedo_var, w, h);
    }
    read_feature(src, aovs, Role::Normal, 3, raw.normal, raw.normal_var, w, h);
    read_feature(src, aovs, Role::Depth, 1, &raw.depth, &raw.depth_var, w, h);
    error.clear();
    return true;
}

void scale_depth(RawPlanes& raw)
{
    float lo = INFINITY, hi = -INFINITY;
    for (float d : raw.depth.px) {
        lo = std::min(lo, d);
        hi = std::max(hi, d);
    }
    const float span = hi - lo;
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

namespace {

float finite_input(float v)
{
    if (!(v == v))
        return 0.0f;
    return std::min(std::max(v, -kInputLimit), kInputLimit);
}

float relu(float v) { return v > 0 ? v : 0.0f; }

}  // namespace

void branch_inputs(const RawPlanes& raw, Branch branch, nn::Tensor& features, nn::Tensor& image)
{
    const int w = raw.width(), h = raw.height();
    const size_t n = size_t(w) * h;
    // Colour in the network domain (0-2), its variance there (3), and the image the kernels
    // filter. Variances move by the Taylor rule of §5.1: Var h(X) ~ h'(mu)² Var X.
    constexpr int kGuides = 10;  // colour 3, albedo 3, normal 3, depth 1: their gradients
    std::vector<float> guides;
    guides.reserve(n * kGuides);
    nn::advise_huge_pages(guides.data(), n * kGuides * sizeof(float));  // a frame: ~80 MB
    guides.resize(n * kGuides);
    features = nn::Tensor();
    nn::reshape(features, h, w, kInputChannels);  // on 2 MB pages: ~300 MB for a frame
    image = nn::Tensor(h, w, 3);
    // Threaded over rows (a frame is ~2M pixels); each value is one thread's, so the result
    // does not depend on the thread count.
    auto for_rows = [h](auto row) {
        tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) {
            for (int y = r.begin(); y != r.end(); ++y)
                row(y);
        });
    };
    for_rows([&](int y) {
        for (size_t i = size_t(y) * w; i < size_t(y + 1) * w; ++i) {
            float* f = features.data.data() + i * kInputChannels;
            float* g = guides.data() + i * kGuides;
            float colour_var_sum = 0;
            for (int c = 0; c < 3; ++c) {
                float colour, variance;
                if (branch == Branch::diffuse) {
                    const float demod = relu(raw.demod[c].px[i]) + kAlbedoEpsilon;
                    const float irradiance = relu(raw.diffuse[c].px[i]) / demod;
                    const float irradiance_var = raw.diffuse_var[c].px[i] / (demod * demod);
                    colour = std::log1p(irradiance);
                    variance = irradiance_var / ((1 + irradiance) * (1 + irradiance));
                    image.data[i * 3 + c] = irradiance;
                } else {
                    const float specular = relu(raw.specular[c].px[i]);
                    colour = std::log1p(specular);
                    variance = raw.specular_var[c].px[i] / ((1 + specular) * (1 + specular));
                    image.data[i * 3 + c] = colour;
                }
                f[c] = colour;
                g[c] = colour;
                colour_var_sum += variance;
            }
            f[3] = std::log1p(relu(colour_var_sum / 3));
            float albedo_var = 0, normal_var = 0;
            for (int c = 0; c < 3; ++c) {
                f[4 + c] = g[3 + c] = std::log1p(relu(raw.albedo[c].px[i]));
                f[7 + c] = g[6 + c] = raw.normal[c].px[i];
                albedo_var += raw.albedo_var[c].px[i];
                normal_var += raw.normal_var[c].px[i];
            }
            f[10] = g[9] = raw.depth.px[i];
            f[11] = std::log1p(relu(albedo_var / 3));
            f[12] = std::log1p(relu(normal_var / 3));
            f[13] = std::log1p(relu(raw.depth_var.px[i]));
        }
    });
    // Gradients (§5.1): forward differences, zero in the last column / row.
    for_rows([&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * w + x;
            float* f = features.data.data() + i * kInputChannels;
            const float* g = guides.data() + i * kGuides;
            for (int k = 0; k < kGuides; ++k) {
                f[14 + k] = x + 1 < w ? g[kGuides + k] - g[k] : 0.0f;
                f[24 + k] = y + 1 < h ? g[size_t(w) * kGuides + k] - g[k] : 0.0f;
            }
            for (int k = 0; k < kInputChannels; ++k)
                f[k] = finite_input(f[k]);
        }
    });
}

}  // namespace kpcn
}  // namespace mcdn
