// mcdn.imageio.so: a procedural OIIO ImageInput. "Reading" `shot.mcdn?in=beauty.exr&...` (or a
// recipe file shot.mcdn with the same keys, one `key = value` per line) reads the render and
// its AOVs, runs the chain, and hands oiiotool the denoised image:
//
//   OIIO_LIBRARY_PATH=build/lib/mcdenoise oiiotool
//     "shot.mcdn?in=beauty.exr&variance=beauty_var.exr" --colorconvert linear sRGB -o out.png
//
// Keys: in (the render, required), variance, halfA, halfB, preset (default: detected), layer,
// colorspace, chain (default denoise: the best chain the inputs allow; or stages such as
// prefilter,nfor,sure,mix), channels (output channels, default the render's own),
// threads, and per-stage settings like nfor.window=19, sure.probes=4, mix.model=net.
// Relative paths in a recipe file are relative to the recipe's folder.
#include <condition_variable>
#include <map>
#include <mutex>
#include <vector>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/version.h"

#include "recipe.h"

using namespace OIIO;

namespace {

using mcdn_plugin::Recipe;

// Reads the inputs and runs the chain the recipe describes.
bool denoise(const Recipe& recipe, ImageBuf& result, std::string& error)
{
    mcdn_plugin::Job job;
    if (!mcdn_plugin::job_from_recipe(recipe, job, error))
        return false;
    ImageBuf merged;
    if (!mcdn::read_inputs(merged, job.inputs)) {
        error = merged.geterror();
        return false;
    }
    mcdn::AovSet aovs;
    if (!mcdn::resolve_aovs(aovs, job.chain.aovs, merged.spec(), error)
        || !aovs.require({ mcdn::Role::Color }, merged.spec(), error)
        || !mcdn::validate_inputs(merged, aovs, error))
        return false;
    ImageBuf chained;
    if (!mcdn::run_chain(chained, merged, job.chain, {}, job.threads)) {
        error = chained.geterror();
        return false;
    }
    // The render's own channels (results in place), or the ones asked for.
    std::vector<std::string> names = job.channels;
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
    ImageSpec& spec = result.specmod();
    for (const char* bookkeeping : { "mcdn:inputs", "mcdn:output_channels" })
        spec.erase_attribute(bookkeeping);
    // What made the image, as oiiotool's own output records it: the version in the
    // plugin's attribute, and appended to the render's Software.
    spec.attribute("mcdn:Version", mcdn::version());
    std::string software = spec.get_string_attribute("Software");
    spec.attribute("Software", (software.empty() ? "" : software + "; ") + mcdn::software_name());
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
        return is_recipe_name(filename) && mcdn_plugin::parse_recipe(filename, recipe, error);
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
        if (m_error.empty())
            m_spec = m_result.spec();
        else {
            // The placeholder says what went wrong wherever its spec is shown (--info -v,
            // iinfo -v): the error is also the first read's.
            m_spec = ImageSpec(1, 1, 1, TypeDesc::FLOAT);
            m_spec.channelnames = { "mcdn_error" };
            m_spec.attribute("mcdn:error", m_error);
            m_spec.attribute("ImageDescription", "mcdn recipe error: " + m_error);
        }
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

    // A recipe's `in` may itself be a recipe: the inner one is computed (and cached) by the
    // same thread, inside the outer one's read. The cache's lock is not held while a recipe
    // is computed, so nesting works; a loop or too deep a nesting is an error instead of a
    // hang (RecipeNesting).
    struct Computed {
        bool done = false;
        ImageBuf result;
        std::string error;
    };

    static ImageBuf computed(const std::string& typed, std::string& error)
    {
        const std::string name = mcdn_plugin::recipe_key(typed);
        static std::mutex mutex;
        static std::condition_variable finished;
        static std::map<std::string, Computed> results;
        thread_local mcdn_plugin::RecipeNesting computing;
        if (!computing.enter(name, error))
            return {};
        {
            std::unique_lock<std::mutex> lock(mutex);
            auto it = results.find(name);
            if (it != results.end()) {
                // Another thread may be computing it: wait for its result.
                finished.wait(lock, [&] { return results.at(name).done; });
                computing.leave();
                error = results.at(name).error;
                return results.at(name).result;
            }
            results.emplace(name, Computed());
        }
        ImageBuf result;
        std::string why;
        try {
            Recipe recipe;
            if (mcdn_plugin::parse_recipe(typed, recipe, why))
                denoise(recipe, result, why);
        } catch (const std::exception& e) {
            why = e.what();
        }
        computing.leave();
        {
            std::lock_guard<std::mutex> lock(mutex);
            Computed& entry = results.at(name);
            entry.done = true;
            entry.result = result;
            entry.error = why;
        }
        finished.notify_all();
        error = why;
        return result;
    }

    ImageBuf m_result;
    std::string m_error;
};

}  // namespace

OIIO_PLUGIN_EXPORTS_BEGIN
OIIO_EXPORT int mcdn_imageio_version = OIIO_PLUGIN_VERSION;
OIIO_EXPORT const char* mcdn_imageio_library_version()
{
    static const std::string name = mcdn::software_name();
    return name.c_str();
}
OIIO_EXPORT ImageInput* mcdn_input_imageio_create() { return new McdnInput; }
OIIO_EXPORT const char* mcdn_input_extensions[] = { "mcdn", nullptr };
OIIO_PLUGIN_EXPORTS_END
