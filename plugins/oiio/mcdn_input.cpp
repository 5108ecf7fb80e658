// mcdn.imageio.so: a procedural OIIO ImageInput. "Reading" `shot.mcdn?in=beauty.exr&...` (or a
// recipe file shot.mcdn with the same keys, one `key = value` per line) reads the render and
// its AOVs, runs the chain, and hands oiiotool the denoised image:
//
//   OIIO_LIBRARY_PATH=build/lib oiiotool
//     "shot.mcdn?in=beauty.exr&variance=beauty_var.exr&halfA=a.exr&halfB=b.exr&preset=cycles&chain=prefilter,nfor"
//     --colorconvert lin_rec709 sRGB -o out.png
//
// Keys: in (the render, required), variance, halfA, halfB, preset, layer, colorspace,
// chain (prefilter,nfor,sure,mix), channels (output channels, default the render's own),
// threads, and per-stage settings like nfor.window=19, sure.probes=4, mix.model=net.
// Relative paths in a recipe file are relative to the recipe's folder.
#include <cctype>
#include <fstream>
#include <map>
#include <mutex>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/chain.h"
#include "mcdn/io.h"

using namespace OIIO;

namespace {

using Recipe = std::map<std::string, std::string>;

std::string url_decode(const std::string& s)
{
    std::string out;
    for (size_t i = 0; i < s.size(); ++i) {
        if (s[i] == '%' && i + 2 < s.size() && std::isxdigit(s[i + 1]) && std::isxdigit(s[i + 2])) {
            out += char(std::stoi(s.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else
            out += s[i];
    }
    return out;
}

// `name` is "file.mcdn", "file.mcdn?k=v&k2=v2" or "?k=v": the file's lines first, the query
// on top.
bool parse_recipe(const std::string& name, Recipe& recipe, std::string& error)
{
    size_t q = name.find('?');
    std::string file = name.substr(0, q);
    if (!file.empty() && Filesystem::is_regular(file)) {
        std::string dir = Filesystem::parent_path(file);
        std::ifstream in(file);
        std::string line;
        int number = 0;
        while (std::getline(in, line)) {
            ++number;
            line = Strutil::strip(line.substr(0, line.find('#')));
            if (line.empty())
                continue;
            size_t eq = line.find('=');
            if (eq == std::string::npos) {
                error = Strutil::fmt::format("{}:{}: expected key = value", file, number);
                return false;
            }
            std::string key = Strutil::strip(line.substr(0, eq));
            std::string value = Strutil::strip(line.substr(eq + 1));
            bool is_path = key == "in" || key == "variance" || key == "halfA" || key == "halfB";
            if (is_path && !value.empty() && value[0] != '/' && !dir.empty())
                value = dir + "/" + value;
            recipe[key] = value;
        }
    } else if (q == std::string::npos) {
        error = Strutil::fmt::format("{}: no such recipe file, and no ?in=... query", name);
        return false;
    }
    if (q != std::string::npos)
        for (const auto& pair : Strutil::splits(name.substr(q + 1), "&")) {
            size_t eq = pair.find('=');
            if (eq == std::string::npos) {
                error = Strutil::fmt::format("'{}': expected key=value in the query", pair);
                return false;
            }
            recipe[url_decode(pair.substr(0, eq))] = url_decode(pair.substr(eq + 1));
        }
    return true;
}

const std::vector<std::string> kKeys = { "in", "variance", "halfA", "halfB", "preset", "layer",
                                         "colorspace", "chain", "channels", "threads" };

// Reads the inputs and runs the chain the recipe describes.
bool denoise(const Recipe& recipe, ImageBuf& result, std::string& error)
{
    for (const auto& [key, value] : recipe)
        if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end()
            && key.find('.') == std::string::npos) {
            error = Strutil::fmt::format("unknown key '{}' (keys: {}, stage.setting)", key,
                                         Strutil::join(kKeys, ", "));
            return false;
        }
    auto get = [&](const std::string& key, const std::string& fallback = "") {
        auto it = recipe.find(key);
        return it == recipe.end() ? fallback : it->second;
    };
    if (get("in").empty()) {
        error = "no render given: add in=FILE";
        return false;
    }
    std::vector<mcdn::InputFile> inputs = { { get("in"), mcdn::InputKind::Mean } };
    for (auto [key, kind] : { std::pair { "variance", mcdn::InputKind::Variance },
                              std::pair { "halfA", mcdn::InputKind::HalfA },
                              std::pair { "halfB", mcdn::InputKind::HalfB } })
        if (!get(key).empty())
            inputs.push_back({ get(key), kind });
    ImageBuf merged;
    if (!mcdn::read_inputs(merged, inputs)) {
        error = merged.geterror();
        return false;
    }
    mcdn::ChainOptions options;
    options.aovs.preset = get("preset", "cycles");
    options.aovs.layer = get("layer");
    options.aovs.colorspace = get("colorspace");
    for (const auto& [key, value] : recipe)
        if (key.find('.') != std::string::npos)
            options.settings[key] = value;
    mcdn::AovSet aovs;
    if (!mcdn::parse_chain(options.stages, get("chain", "prefilter,nfor"), error)
        || !mcdn::resolve_aovs(aovs, options.aovs, merged.spec(), error)
        || !aovs.require({ mcdn::Role::Color }, merged.spec(), error)
        || !mcdn::validate_inputs(merged, aovs, error))
        return false;
    ImageBuf chained;
    if (!mcdn::run_chain(chained, merged, options, {}, Strutil::stoi(get("threads", "0")))) {
        error = chained.geterror();
        return false;
    }
    // The render's own channels (results in place), or the ones asked for.
    std::vector<std::string> names = Strutil::splits(get("channels"), ",");
    if (names.empty())
        names = Strutil::splits(chained.spec().get_string_attribute("mcdn:output_channels"), "\n");
    std::vector<int> order;
    for (const auto& n : names) {
        int c = chained.spec().channelindex(n);
        if (c < 0) {
            error = Strutil::fmt::format("channel '{}' is not in the result; channels there: {}",
                                         n, mcdn::channel_list(chained.spec()));
            return false;
        }
        order.push_back(c);
    }
    result = ImageBufAlgo::channels(chained, int(order.size()), order);
    for (const char* bookkeeping : { "mcdn:inputs", "mcdn:output_channels" })
        result.specmod().erase_attribute(bookkeeping);
    return true;
}

class McdnInput final : public ImageInput {
public:
    const char* format_name() const override { return "mcdn"; }
    int supports(string_view feature) const override { return feature == "procedural"; }

    bool valid_file(const std::string& filename) const override
    {
        Recipe recipe;
        std::string error;
        return is_recipe_name(filename) && parse_recipe(filename, recipe, error);
    }

    // oiiotool (2.4) treats a procedural input whose open() fails as "file not found" and
    // then aborts. So a recipe that fails opens as a 1x1 placeholder and the error surfaces
    // from the first read, as an ordinary oiiotool read error. The result is computed once
    // per process and recipe: oiiotool and its ImageCache open an input several times.
    bool open(const std::string& name, ImageSpec& newspec) override
    {
        if (!is_recipe_name(name)) {
            errorfmt("{}: not an mcdn recipe (name.mcdn or name.mcdn?in=...)", name);
            return false;
        }
        m_result = computed(name, m_error);
        m_spec = m_error.empty() ? m_result.spec() : ImageSpec(1, 1, 1, TypeDesc::FLOAT);
        newspec = m_spec;
        return true;
    }

    bool close() override
    {
        m_result.clear();
        return true;
    }

    bool read_native_scanline(int subimage, int miplevel, int y, int z, void* data) override
    {
        if (!m_error.empty()) {
            errorfmt("mcdn: {}", m_error);
            return false;
        }
        if (subimage != 0 || miplevel != 0)
            return false;
        ROI row(m_spec.x, m_spec.x + m_spec.width, y, y + 1, z, z + 1, 0, m_spec.nchannels);
        return m_result.get_pixels(row, TypeDesc::FLOAT, data);
    }

private:
    static bool is_recipe_name(const std::string& name)
    {
        std::string file = name.substr(0, name.find('?'));
        return Strutil::iends_with(file, ".mcdn");
    }

    static ImageBuf computed(const std::string& name, std::string& error)
    {
        static std::mutex mutex;
        static std::map<std::string, std::pair<ImageBuf, std::string>> results;
        std::lock_guard<std::mutex> lock(mutex);
        auto it = results.find(name);
        if (it == results.end()) {
            ImageBuf result;
            std::string why;
            Recipe recipe;
            try {
                if (parse_recipe(name, recipe, why))
                    denoise(recipe, result, why);
            } catch (const std::exception& e) {
                why = e.what();
            }
            it = results.emplace(name, std::make_pair(std::move(result), why)).first;
        }
        error = it->second.second;
        return it->second.first;
    }

    ImageBuf m_result;
    std::string m_error;
};

}  // namespace

OIIO_PLUGIN_EXPORTS_BEGIN
OIIO_EXPORT int mcdn_imageio_version = OIIO_PLUGIN_VERSION;
OIIO_EXPORT const char* mcdn_imageio_library_version() { return "mcdenoise 0.1"; }
OIIO_EXPORT ImageInput* mcdn_input_imageio_create() { return new McdnInput; }
OIIO_EXPORT const char* mcdn_input_extensions[] = { "mcdn", nullptr };
OIIO_PLUGIN_EXPORTS_END
