// mcdn.imageio.so: a procedural OIIO ImageInput. "Reading" `shot.mcdn?in=beauty.exr&...` (or a
// recipe file shot.mcdn with the same keys, one `key = value` per line) reads the render and
// its AOVs, runs the chain, and hands oiiotool the denoised image:
//
//   OIIO_LIBRARY_PATH=build/lib/mcdenoise oiiotool
//     "shot.mcdn?in=beauty.exr&variance=beauty_var.exr" --colorconvert linear sRGB -o out.png
//
// The image has the render's channel types (mcdn::written_types), its pixels held in half
// when all are half, else in float.
// Keys: in (the render, required), variance, halfA, halfB, preset (default: detected), layer,
// colorspace, chain (default denoise: the best chain the inputs allow; or stages such as
// prefilter,nfor,sure,mix), channels (output channels, default the render's own),
// threads, and per-stage settings like nfor.window=19, sure.probes=4, mix.model=net.
// Relative paths in a recipe file are relative to the recipe's folder.
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/chain.h"
#include "mcdn/io.h"
#include "mcdn/stages.h"
#include "mcdn/version.h"

#include "recipe.h"

using namespace OIIO;

namespace {

using mcdn_plugin::Recipe;

// Reads the inputs and runs the chain the recipe describes: `result` in half when every
// channel is, else in float; `types` the type of each of its channels in the image handed
// on (mcdn::written_types: the render's).
bool denoise(const Recipe& recipe, ImageBuf& result, std::vector<TypeDesc>& types,
             std::string& error)
{
    mcdn_plugin::Job job;
    if (!mcdn_plugin::job_from_recipe(recipe, job, error))
        return false;
    // Of the variance and half files, what the chain's stages read (a Blender frame's four
    // files of 39 channels each: 42 merged channels for oidn,sure,mix rather than 70); every
    // channel where the recipe asks for channels by name.
    mcdn::InputSelection selection;
    if (job.channels.empty()) {
        selection = mcdn::chain_input_selection(job.chain.stages, job.chain.settings,
                                                mcdn::gives_variance(job.inputs));
        selection.aovs = job.chain.aovs;
    }
    // The inputs a band of rows at a time, as mcdntool streams them (mcdn/chain.h): the
    // result and one band of the inputs are in memory, never the inputs' whole frame.
    mcdn::InputRows rows;
    if (!rows.open(job.inputs, selection, error))
        return false;
    const ImageSpec& input = rows.spec();
    mcdn::AovSet aovs;
    if (!mcdn::resolve_aovs(aovs, job.chain.aovs, input, error)
        || !aovs.require({ mcdn::Role::Color }, input, error))
        return false;
    // No -v in oiiotool: the repaired tiles are said on the result (mcdn:halves_repaired).
    mcdn::InputChecks checks;
    auto read = [&](ImageBuf& band, int y0, int y1, const std::vector<bool>& channels,
                    std::string& read_error) {
        return rows.read(band, y0, y1, read_error, channels)
               && checks.check(band, aovs, read_error);
    };
    // Each band's own rows of the render's own channels (results in place), or of the ones
    // asked for, into the result.
    std::vector<int> order;
    std::vector<float> own_rows;  // a band's own rows of them, in float
    int64_t clamped = 0;
    job.chain.output_channels_only = job.channels.empty();
    mcdn::set_bands_from_environment(job.chain);
    mcdn::BandCounts counts;  // the safety nets' over the bands, said on the result
    auto sink = [&](const ImageBuf& band, const ROI& own, std::string& sink_error) {
        counts.add(band.spec());
        if (!result.initialized()) {
            std::vector<std::string> names = job.channels;
            if (names.empty())
                names =
                    Strutil::splits(band.spec().get_string_attribute("mcdn:output_channels"), "\n");
            for (const auto& n : names) {
                const int c = band.spec().channelindex(n);
                if (c < 0) {
                    sink_error = Strutil::fmt::format(
                        "channel '{}' is not in the result; channels there: {}", n,
                        mcdn::channel_list(band.spec()));
                    return false;
                }
                order.push_back(c);
            }
            types = mcdn::written_types(band.spec(), names);
            ImageSpec spec = band.spec();
            spec.y = input.y;
            spec.height = input.height;
            spec.nchannels = int(order.size());
            spec.channelnames = names;
            spec.channelformats.clear();
            spec.alpha_channel = spec.channelindex("A");
            spec.z_channel = spec.channelindex("Z");
            // Held in half when every channel is (half the memory), else in float.
            const bool all_half = std::all_of(types.begin(), types.end(),
                                              [](TypeDesc t) { return t == TypeDesc::HALF; });
            spec.set_format(all_half ? TypeDesc::HALF : TypeDesc::FLOAT);
            result.reset(spec, InitializePixels::No);
        }
        // The band's own rows of the output channels, in float.
        const size_t nch = order.size();
        own_rows.resize(size_t(own.npixels()) * nch);
        for (size_t i = 0; i < nch; ++i) {
            ROI from = own;
            from.chbegin = order[i];
            from.chend = order[i] + 1;
            if (!band.get_pixels(from, TypeDesc::FLOAT, own_rows.data() + i, nch * sizeof(float))) {
                sink_error = band.geterror();
                return false;
            }
        }
        // A half channel's values beyond half's range become +-65504, not Inf, as mcdntool
        // writes them; counted on the result (mcdn:clamped_to_half).
        for (size_t k = 0; k < own_rows.size(); ++k) {
            float& v = own_rows[k];
            if (types[k % nch] == TypeDesc::HALF && std::isfinite(v)
                && std::fabs(v) > mcdn::kHalfMax) {
                v = std::copysign(mcdn::kHalfMax, v);
                ++clamped;
            }
        }
        ROI to = own;
        to.chbegin = 0;
        to.chend = int(nch);
        if (!result.set_pixels(to, TypeDesc::FLOAT, own_rows.data())) {
            sink_error = result.geterror();
            return false;
        }
        return true;
    };
    if (!mcdn::run_chain(input, read, job.chain, sink, error, job.threads))
        return false;
    counts.set(result.specmod());
    ImageSpec& spec = result.specmod();
    for (const char* bookkeeping : { mcdn::kInputsAttribute, "mcdn:output_channels" })
        spec.erase_attribute(bookkeeping);
    // What made the image, as oiiotool's own output records it: the version in the
    // plugin's attribute, and appended to the render's Software.
    spec.attribute("mcdn:Version", mcdn::version());
    if (checks.repaired_tiles() > 0)
        spec.attribute("mcdn:halves_repaired", checks.repaired_tiles());
    if (clamped > 0)
        spec.attribute("mcdn:clamped_to_half", int(std::min<int64_t>(clamped, INT32_MAX)));
    std::string software = spec.get_string_attribute("Software");
    spec.attribute("Software", (software.empty() ? "" : software + "; ") + mcdn::software_name());
    return true;
}

class McdnInput final : public ImageInput {
public:
    const char* format_name() const override { return "mcdn"; }
    int supports(string_view feature) const override { return feature == "procedural"; }

    // Every name.mcdn is ours: a recipe that does not parse opens with its error (open())
    // rather than as OIIO's "File does not exist".
    bool valid_file(const std::string& filename) const override { return is_recipe_name(filename); }

    // oiiotool (2.4) treats a procedural input whose open() fails as "file not found" and
    // then aborts. So a recipe that fails opens as a 1x1 placeholder and the error surfaces
    // from the first read, as an ordinary oiiotool read error (and mcdntool, reading a
    // recipe, reports the placeholder's mcdn:error). The result is computed once per
    // recipe and state of its files (computed()): oiiotool and its ImageCache open an input
    // several times.
    bool open(const std::string& name, ImageSpec& newspec) override
    {
        if (!is_recipe_name(name)) {
            errorfmt("{}: not an mcdn recipe (name.mcdn or name.mcdn?in=...)", name);
            return false;
        }
        m_entry = computed(name, m_error);
        if (m_error.empty()) {
            // Each channel as the render had it (a half render gives a half image, as
            // oiiotool keeps it); mixed types are held in float and converted as read.
            m_spec = m_entry->result.spec();
            mcdn::set_channel_types(m_spec, m_entry->types);
        } else {
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
        m_entry.reset();
        return true;
    }

    bool read_native_scanline(int subimage, int miplevel, int y, int z, void* data) override
    {
        if (!m_error.empty()) {
            errorfmt("mcdn: {}", m_error);
            return false;
        }
        if (subimage != 0 || miplevel != 0 || !m_entry)
            return false;
        ROI row(m_spec.x, m_spec.x + m_spec.width, y, y + 1, z, z + 1, 0, m_spec.nchannels);
        if (m_spec.channelformats.empty())
            return m_entry->result.get_pixels(row, m_spec.format, data);
        // Mixed types: each pixel's channels packed, each in its own type.
        m_row.resize(size_t(m_spec.width) * m_spec.nchannels);
        if (!m_entry->result.get_pixels(row, TypeDesc::FLOAT, m_row.data()))
            return false;
        auto* out = static_cast<char*>(data);
        for (size_t i = 0; i < m_row.size(); ++i) {
            const TypeDesc type = m_spec.channelformats[i % size_t(m_spec.nchannels)];
            convert_pixel_values(TypeDesc::FLOAT, &m_row[i], type, out, 1);
            out += type.size();
        }
        return true;
    }

private:
    static bool is_recipe_name(const std::string& name)
    {
        std::string file = name.substr(0, name.find('?'));
        return Strutil::iends_with(file, ".mcdn");
    }

    struct Computed {
        bool done = false;
        ImageBuf result;              // half where every channel is, else float
        std::vector<TypeDesc> types;  // each channel's type in the image handed on
        std::string error;
    };
    // Results no open input holds that stay for the next open (oiiotool opens an input
    // several times); older ones are freed, so a process reading many recipes holds a few.
    static constexpr int kKeptResults = 2;

    // A recipe's `in` may itself be a recipe: the inner one is computed (and cached) by the
    // same thread, inside the outer one's read. The cache's lock is not held while a recipe
    // is computed, so nesting works; a loop or too deep a nesting is an error instead of a
    // hang (RecipeNesting). Results are keyed by the recipe and the state of its files on
    // disk (recipe_stamp): an edited recipe or a changed input is computed again.
    static std::shared_ptr<Computed> computed(const std::string& typed, std::string& error)
    {
        const std::string name = mcdn_plugin::recipe_key(typed);
        const std::string key = name + "\n" + mcdn_plugin::recipe_stamp(typed);
        static std::mutex mutex;
        static std::condition_variable finished;
        static std::map<std::string, std::shared_ptr<Computed>> results;
        static std::vector<std::string> order;  // the keys of `results`, oldest first
        thread_local mcdn_plugin::RecipeNesting computing;
        if (!computing.enter(name, error))
            return nullptr;
        std::shared_ptr<Computed> entry;
        {
            std::unique_lock<std::mutex> lock(mutex);
            auto it = results.find(key);
            if (it != results.end()) {
                // Another thread may be computing it: wait for its result.
                entry = it->second;
                finished.wait(lock, [&] { return entry->done; });
                computing.leave();
                error = entry->error;
                return entry;
            }
            entry = std::make_shared<Computed>();
            results.emplace(key, entry);
            order.push_back(key);
        }
        ImageBuf result;
        std::vector<TypeDesc> types;
        std::string why;
        try {
            Recipe recipe;
            if (mcdn_plugin::parse_recipe(typed, recipe, why))
                denoise(recipe, result, types, why);
        } catch (const std::exception& e) {
            why = e.what();
        }
        computing.leave();
        {
            std::lock_guard<std::mutex> lock(mutex);
            entry->done = true;
            entry->result = std::move(result);
            entry->types = std::move(types);
            entry->error = why;
            // Newest first: results nobody holds (the map's is the only reference) beyond
            // kKeptResults are freed.
            int kept = 0;
            for (size_t i = order.size(); i-- > 0;) {
                auto found = results.find(order[i]);
                const bool unheld = found->second->done && found->second.use_count() == 1;
                if (unheld && ++kept > kKeptResults) {
                    results.erase(found);
                    order.erase(order.begin() + long(i));
                }
            }
        }
        finished.notify_all();
        error = why;
        return entry;
    }

    std::shared_ptr<Computed> m_entry;
    std::string m_error;
    std::vector<float> m_row;  // a row in float, for a read of mixed types
};

}  // namespace

OIIO_PLUGIN_EXPORTS_BEGIN
OIIO_EXPORT int mcdn_imageio_version = OIIO_PLUGIN_VERSION;
OIIO_EXPORT const char* mcdn_imageio_library_version()
{
    static const std::string name = mcdn::software_name();
    return name.c_str();
}
OIIO_EXPORT ImageInput* mcdn_input_imageio_create()
{
    return new McdnInput;
}
OIIO_EXPORT const char* mcdn_input_extensions[] = { "mcdn", nullptr };
OIIO_PLUGIN_EXPORTS_END
