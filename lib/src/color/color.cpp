// Colour management through OpenColorIO (see mcdn/color.h). Conversions between
// scene-linear spaces are 3x3 matrices: we read the matrix off the OCIO processor once and
// apply it (and its square, to variances) ourselves, to exactly the channels we mean. From a
// display or log encoding (an LDR file's sRGB) OCIO converts each colour pixel itself.
#include "mcdn/color.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>

#include <OpenColorIO/OpenColorIO.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/channels.h"
#include "core/planar.h"
#include "color/primaries.h"
#include "mcdn/version.h"

namespace OCIO = OCIO_NAMESPACE;

namespace mcdn {

using OIIO::Strutil::fmt::format;

namespace {

// Configs are parsed once per path; OCIO configs are immutable and thread-safe to share.
OCIO::ConstConfigRcPtr load_config(std::string& error)
{
    static std::mutex mutex;
    static std::map<std::string, OCIO::ConstConfigRcPtr> cache;
    std::string path = ocio_config_path();
    std::lock_guard<std::mutex> lock(mutex);
    auto it = cache.find(path);
    if (it != cache.end())
        return it->second;
    try {
        auto config = OCIO::Config::CreateFromFile(path.c_str());
        cache[path] = config;
        return config;
    } catch (const OCIO::Exception& e) {
        error = format("OCIO config {}: {}", path, e.what());
        return {};
    }
}

// The channels "noisy.<name>" of `names` (sure's record of a render's colour or an extra's,
// which mix reads beside the result), empty unless all are there.
std::vector<int> noisy_channels(const ImageSpec& spec, const std::vector<std::string>& names)
{
    std::vector<int> noisy;
    for (const std::string& name : names)
        if (spec.channelindex("noisy." + name) >= 0)
            noisy.push_back(spec.channelindex("noisy." + name));
    return noisy.size() == names.size() ? noisy : std::vector<int> {};
}

// The colour-carrying channel groups of an AOV set, and whether each is a variance.
struct ColorGroup {
    std::vector<int> channels;
    bool variance;
};

std::vector<ColorGroup> color_groups(const ImageBuf& buf, const AovSet& aovs)
{
    std::vector<ColorGroup> groups;
    // Each group once: a light pass may be a role (Blender's DiffDir, Arnold's diffuse) and
    // an extra.
    auto push_back = [&groups](ColorGroup group) {
        for (const ColorGroup& g : groups)
            if (g.channels == group.channels)
                return;
        groups.push_back(std::move(group));
    };
    for (Role r : { Role::Color, Role::ColorA, Role::ColorB, Role::Albedo, Role::AlbedoA,
                    Role::AlbedoB, Role::Diffuse, Role::Specular, Role::DiffuseColor,
                    Role::DiffuseDirect, Role::DiffuseIndirect, Role::GlossyColor,
                    Role::GlossyDirect, Role::GlossyIndirect, Role::Emission, Role::Environment })
        if (aovs.has(r))
            push_back({ aovs.channels(r), false });
    for (Role r : { Role::ColorVariance, Role::AlbedoVariance })
        if (aovs.has(r))
            push_back({ aovs.channels(r), true });
    for (const auto& extra : aovs.extras())
        if (extra.channels.size() == 3)
            for (const auto* face :
                 { &extra.channels, &extra.half_a, &extra.half_b, &extra.variance })
                if (!face->empty())
                    push_back({ *face, face == &extra.variance });
    for (const auto& extra : aovs.extras())
        if (extra.channels.size() == 3) {
            const std::vector<int> noisy = noisy_channels(buf.spec(), extra.names);
            if (!noisy.empty())
                push_back({ noisy, false });
        }
    const std::vector<int> noisy = noisy_channels(buf.spec(), { "R", "G", "B" });
    if (!noisy.empty())
        push_back({ noisy, false });
    return groups;
}

}  // namespace

std::string ocio_config_path()
{
    return install_paths().ocio_config;
}

std::string working_colorspace()
{
    std::string error;
    auto config = load_config(error);
    if (!config)
        return "scene_linear";
    auto cs = config->getColorSpace(OCIO::ROLE_SCENE_LINEAR);
    return cs ? cs->getName() : "scene_linear";
}

namespace {

// OIIO's EXR reader tags every file "Linear": linear, but not which primaries.
bool says_only_linear(const std::string& tag)
{
    return OIIO::Strutil::iequals(tag, "linear") || OIIO::Strutil::iequals(tag, "scene_linear");
}

}  // namespace

bool input_colorspace(std::string& name, std::string& why, const AovSpec& aovs,
                      const ImageSpec& image, std::string& error)
{
    auto config = load_config(error);
    if (!config)
        return false;
    auto known = [&](const std::string& n) { return config->getColorSpace(n.c_str()); };
    // A buffer run_in_working_space converted is in the working space, whatever the spec says.
    if (image.get_int_attribute(kInWorkingSpaceAttribute) == 1) {
        name = working_colorspace();
        why = "converted already";
        return true;
    }
    if (!aovs.colorspace.empty()) {
        if (!known(aovs.colorspace)) {
            error = format("colour space '{}' (--aov:colorspace) is not in the OCIO config {}",
                           aovs.colorspace, ocio_config_path());
            return false;
        }
        name = known(aovs.colorspace)->getName();
        why = "--aov:colorspace";
        return true;
    }
    const std::string tagged = image.get_string_attribute("oiio:ColorSpace");
    if (!tagged.empty() && !says_only_linear(tagged)) {
        if (!known(tagged)) {
            error = format("the file says oiio:ColorSpace '{}', which the OCIO config {} does "
                           "not know: give --aov:colorspace=NAME",
                           tagged, ocio_config_path());
            return false;
        }
        name = known(tagged)->getName();
        why = "the file's oiio:ColorSpace '" + tagged + "'";
        return true;
    }
    const OIIO::ParamValue* chroma = image.find_attribute("chromaticities");
    if (chroma && chroma->type().basetype == OIIO::TypeDesc::FLOAT
        && chroma->nvalues() * chroma->type().basevalues() >= 8) {
        const float* xy = static_cast<const float*>(chroma->data());
        for (const Primaries& p : kPrimaries) {
            bool same = true;
            for (int i = 0; i < 8; ++i)
                same = same && std::abs(xy[i] - p.xy[i]) < 2e-3f;
            if (same && known(p.colorspace)) {
                name = known(p.colorspace)->getName();
                why = format("the file's chromaticities ({} primaries)", p.name);
                return true;
            }
        }
        // Other primaries (P3, XYZ, a camera's): their own matrix (primaries_to_rec709).
        std::array<double, 9> m;
        name = format("{}{},{} {},{} {},{} {},{}", kPrimariesName, xy[0], xy[1], xy[2], xy[3],
                      xy[4], xy[5], xy[6], xy[7]);
        if (!primaries_to_rec709(m, name, error))
            return false;
        why = "the file's chromaticities: converted by the matrix of their primaries";
        return true;
    }
    name = working_colorspace();
    why = tagged.empty() ? "no colour-space tag: the config's scene_linear"
                         : "the file's oiio:ColorSpace '" + tagged + "': the config's scene_linear";
    return true;
}

std::string input_colorspace(const AovSpec& aovs, const ImageSpec& image)
{
    std::string name, why, error;
    return input_colorspace(name, why, aovs, image, error) ? name : working_colorspace();
}

namespace {

// OCIO's CPU conversion between two spaces of the config.
OCIO::ConstCPUProcessorRcPtr cpu_processor(const std::string& from, const std::string& to,
                                           std::string& error)
{
    auto config = load_config(error);
    if (!config)
        return {};
    for (const auto& name : { from, to })
        if (!is_primaries(name) && !config->getColorSpace(name.c_str())) {
            error = format("unknown colour space '{}' in {}", name, ocio_config_path());
            return {};
        }
    try {
        if (is_primaries(from) || is_primaries(to)) {
            // A file's own primaries: their matrix to Rec.709, then OCIO from there.
            Matrix m, inverse;
            if (!primaries_to_rec709(m, is_primaries(from) ? from : to, error))
                return {};
            invert(inverse, m);
            const Matrix& use = is_primaries(from) ? m : inverse;
            double m44[16] = { use[0], use[1], use[2], 0, use[3], use[4], use[5], 0,
                               use[6], use[7], use[8], 0, 0,      0,      0,      1 };
            auto matrix = OCIO::MatrixTransform::Create();
            matrix->setMatrix(m44);
            auto space = OCIO::ColorSpaceTransform::Create();
            const char* rec709 = kPrimaries[0].colorspace;
            space->setSrc(is_primaries(from) ? rec709 : from.c_str());
            space->setDst(is_primaries(from) ? to.c_str() : rec709);
            auto group = OCIO::GroupTransform::Create();
            if (is_primaries(from)) {
                group->appendTransform(matrix);
                group->appendTransform(space);
            } else {
                group->appendTransform(space);
                group->appendTransform(matrix);
            }
            return config->getProcessor(group)->getDefaultCPUProcessor();
        }
        return config->getProcessor(from.c_str(), to.c_str())->getDefaultCPUProcessor();
    } catch (const OCIO::Exception& e) {
        error = format("no conversion from '{}' to '{}': {}", from, to, e.what());
        return {};
    }
}

// A display or log encoding (an 8-bit PNG's sRGB) has no matrix: OCIO converts each pixel of
// the colour channels itself, the encoding's curve included. A variance has no such
// conversion (the curve's slope differs per value): an error.
bool convert_encoded(ImageBuf& buf, const AovSet& aovs, const std::string& from,
                     const std::string& to, const OCIO::ConstCPUProcessorRcPtr& cpu,
                     std::string& error)
{
    const auto groups = color_groups(buf, aovs);
    for (const auto& group : groups)
        if (group.variance) {
            error = format("'{}' is not linear (a display or log encoding): a variance in it "
                           "cannot be converted to '{}'; give the render in a linear space",
                           from == working_colorspace() ? to : from,
                           from == working_colorspace() ? from : to);
            return false;
        }
    const int nch = buf.nchannels();
    float* pixels = static_cast<float*>(buf.localpixels());
    const size_t npixels = buf.spec().image_pixels();
    for (const auto& group : groups) {
        const int* c = group.channels.data();
        for (size_t p = 0; p < npixels; ++p) {
            float* px = pixels + p * nch;
            float rgb[3] = { px[c[0]], px[c[1]], px[c[2]] };
            cpu->applyRGB(rgb);
            for (int i = 0; i < 3; ++i)
                px[c[i]] = sanitize(rgb[i]);
        }
    }
    return true;
}

// The matrix of a linear conversion; false (error unset) when it is not linear.
bool matrix_of(std::array<double, 9>& m, const OCIO::ConstCPUProcessorRcPtr& cpu)
{
    for (int j = 0; j < 3; ++j) {
        float e[3] = { 0, 0, 0 }, big[3] = { 0, 0, 0 };
        e[j] = 1.0f;
        big[j] = 4.0f;
        cpu->applyRGB(e);
        cpu->applyRGB(big);
        for (int i = 0; i < 3; ++i) {
            m[i * 3 + j] = e[i];
            if (std::fabs(big[i] - 4.0 * e[i]) > 1e-4 * (1.0 + std::fabs(big[i])))
                return false;
        }
    }
    float zero[3] = { 0, 0, 0 };
    cpu->applyRGB(zero);
    return std::fabs(zero[0]) + std::fabs(zero[1]) + std::fabs(zero[2]) <= 1e-6;
}

}  // namespace

bool linear_transform(std::array<double, 9>& m, const std::string& from, const std::string& to,
                      std::string& error)
{
    auto cpu = cpu_processor(from, to, error);
    if (!cpu)
        return false;
    if (!matrix_of(m, cpu)) {
        error = format("the conversion from '{}' to '{}' is not scene-linear: mcdn ops need "
                       "linear radiance",
                       from, to);
        return false;
    }
    return true;
}

bool convert_color_channels(ImageBuf& buf, const AovSet& aovs, const std::string& from,
                            const std::string& to, std::string& error, int nthreads)
{
    if (from == to)
        return true;
    auto cpu = cpu_processor(from, to, error);
    if (!cpu)
        return false;
    const int nch = buf.nchannels();
    float* pixels = static_cast<float*>(buf.localpixels());
    if (!pixels || buf.spec().format != OIIO::TypeDesc::FLOAT) {
        error = "colour conversion needs a local float buffer";
        return false;
    }
    std::array<double, 9> m;
    if (!matrix_of(m, cpu))
        return convert_encoded(buf, aovs, from, to, cpu, error);
    const auto groups = color_groups(buf, aovs);
    for_pixel_chunks(buf.spec().image_pixels(), nthreads, [&](size_t begin, size_t end) {
        for (const auto& group : groups) {
            std::array<double, 9> w = m;
            if (group.variance)
                for (double& v : w)
                    v *= v;  // Var[Mx]_i = sum_j M_ij^2 Var[x_j]
            const int* c = group.channels.data();
            for (size_t p = begin; p < end; ++p) {
                float* px = pixels + p * nch;
                double in[3] = { px[c[0]], px[c[1]], px[c[2]] };
                for (int i = 0; i < 3; ++i)
                    px[c[i]] = sanitize(
                        float(w[i * 3] * in[0] + w[i * 3 + 1] * in[1] + w[i * 3 + 2] * in[2]));
            }
        }
    });
    return true;
}

namespace {

// Below this a factor channel holds no light to divide out: Cycles' own rule then gives the
// pass the mean of the other channels' quotients (its safe_divide_even_color), 0 without any.
constexpr float kSmallestFactor = 1e-4f;

/// Extras that hold light divided by a factor (AovSet::Extra::factor), as light: each face
/// (mean, halves: by their own factor where the inputs have it; variance: by its square)
/// times the factor, or with `divide` the way back.
void scale_factored_extras(ImageBuf& buf, const AovSet& aovs, bool divide, int nthreads)
{
    const int nch = buf.nchannels();
    float* pixels = static_cast<float*>(buf.localpixels());
    struct Face {
        std::vector<int> pass, factor;
        bool variance;
    };
    std::vector<Face> faces;
    for (const AovSet::Extra& extra : aovs.extras()) {
        if (extra.factor.size() != 3 || extra.channels.size() != 3)
            continue;
        const bool own_halves = extra.factor_a.size() == 3 && extra.factor_b.size() == 3;
        for (Face face : { Face { extra.channels, extra.factor, false },
                           Face { extra.half_a, own_halves ? extra.factor_a : extra.factor, false },
                           Face { extra.half_b, own_halves ? extra.factor_b : extra.factor, false },
                           Face { extra.variance, extra.factor, true },
                           Face { noisy_channels(buf.spec(), extra.names), extra.factor, false } })
            if (face.pass.size() == 3)
                faces.push_back(std::move(face));
    }
    // A pixel at a time, every face of it (one pass over the frame's cache lines): a face
    // writes only its own pass's channels and reads only its own and its factor's.
    for_pixel_chunks(buf.spec().image_pixels(), nthreads, [&](size_t begin, size_t end) {
        for (size_t p = begin; p < end; ++p)
            for (const Face& face : faces) {
                const float smallest =
                    face.variance ? kSmallestFactor * kSmallestFactor : kSmallestFactor;
                float* px = pixels + p * nch;
                float f[3], v[3];
                bool lit[3];
                for (int c = 0; c < 3; ++c) {
                    f[c] = px[face.factor[c]];
                    if (face.variance)
                        f[c] *= f[c];
                    lit[c] = std::abs(f[c]) > smallest;
                    v[c] = !divide  ? px[face.pass[c]] * f[c]
                           : lit[c] ? px[face.pass[c]] / f[c]
                                    : 0.0f;
                }
                for (int c = 0; c < 3 && divide && !face.variance; ++c) {
                    if (lit[c])
                        continue;
                    float sum = 0.0f;
                    int n = 0;
                    for (int k = 0; k < 3; ++k)
                        if (lit[k]) {
                            sum += v[k];
                            ++n;
                        }
                    v[c] = n ? sum / float(n) : 0.0f;
                }
                for (int c = 0; c < 3; ++c)
                    px[face.pass[c]] = face.variance ? sanitize_variance(v[c]) : sanitize(v[c]);
            }
    });
}

}  // namespace

bool needs_working_conversion(const ImageSpec& image, const std::string& from, const AovSet& aovs)
{
    if (image.get_int_attribute(kInWorkingSpaceAttribute) == 1)
        return false;
    return from != working_colorspace() || aovs.has_factored_extras();
}

bool into_working_space(ImageBuf& buf, const AovSet& aovs, const std::string& from,
                        std::string& error, int nthreads)
{
    if (buf.spec().format != OIIO::TypeDesc::FLOAT || !buf.localpixels()) {
        error = "colour conversion needs a local float buffer";
        return false;
    }
    scale_factored_extras(buf, aovs, false, nthreads);
    if (!convert_color_channels(buf, aovs, from, working_colorspace(), error, nthreads))
        return false;
    buf.specmod().attribute(kInWorkingSpaceAttribute, 1);
    return true;
}

bool out_of_working_space(ImageBuf& buf, const AovSet& aovs, const std::string& to,
                          std::string& error, int nthreads)
{
    if (buf.spec().format != OIIO::TypeDesc::FLOAT || !buf.localpixels()) {
        error = "colour conversion needs a local float buffer";
        return false;
    }
    buf.specmod().erase_attribute(kInWorkingSpaceAttribute);
    if (!convert_color_channels(buf, aovs, working_colorspace(), to, error, nthreads))
        return false;
    scale_factored_extras(buf, aovs, true, nthreads);
    return true;
}

bool run_in_working_space(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec,
                          const char* op_name,
                          const std::function<bool(ImageBuf& dst, const ImageBuf& src)>& op)
{
    std::string from, why, error;
    if (!input_colorspace(from, why, spec, src.spec(), error)) {
        dst.errorfmt("{}: {}", op_name, error);
        return false;
    }
    AovSet aovs;
    if (!resolve_aovs(aovs, spec, src.spec(), error)) {
        dst.errorfmt("{}: {}", op_name, error);
        return false;
    }
    if (!needs_working_conversion(src.spec(), from, aovs))
        return op(dst, src);
    ImageBuf converted = copy_with_channels(src, {});
    if (!converted.localpixels()) {
        dst.errorfmt("{}: out of memory for a float copy of the {}x{} frame of {} channels",
                     op_name, src.spec().width, src.spec().height, src.spec().nchannels);
        return false;
    }
    if (!into_working_space(converted, aovs, from, error)) {
        dst.errorfmt("{}: colorspace {}: {}", op_name, from, error);
        return false;
    }
    if (!op(dst, converted))
        return false;
    if (!resolve_aovs(aovs, spec, dst.spec(), error)
        || !out_of_working_space(dst, aovs, from, error)) {
        dst.errorfmt("{}: colorspace {}: {}", op_name, from, error);
        return false;
    }
    return true;
}

}  // namespace mcdn
