// The session of one frame (session.h): its inputs read lazily, the denoisers queued and run,
// the current image and the chain SURE takes; the commands are builtins.cpp and stages.cpp.

#include "session.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <mutex>
#include <set>
#include <tuple>

#include <fnmatch.h>
#include <unistd.h>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>
#include <OpenImageIO/timer.h>

#include "mcdn/chain.h"
#include "mcdn/choose.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/frames.h"
#include "mcdn/metrics.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"
#include "mcdn/settings.h"
#include "mcdn/skip.h"

namespace mcdntool {

using mcdn::Role;
using OIIO::ImageBuf;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

bool Session::load(std::string& error)
{
    if (!load_inputs(error))
        return false;
    std::vector<Queued> queue;
    std::swap(queue, m_queue);
    capture_input_features(queue);
    for (const auto& stage : queue) {
        // The first denoiser's input is kept for a later --sure, which reruns the chain: moved
        // there, not copied (an 8K frame of 40 channels is 5.3 GB).
        bool first = m_applied.empty();
        if (first)
            m_chain_input = std::move(m_image);
        if (!apply_to(stage.name, first ? m_chain_input : m_image, stage.op, error))
            return false;
        m_applied.push_back(stage);  // after apply_to(), which starts a new chain
    }
    return true;
}

void say_once(const std::string& line)
{
    static std::mutex mutex;
    static std::set<std::string> said;
    std::lock_guard<std::mutex> lock(mutex);
    if (said.insert(line).second)
        std::cerr << line;
}

mcdn::ProgressCallback Session::progress() const
{
    if (!verbose)
        return {};
    if (!isatty(STDERR_FILENO)) {
        // A log (a farm's): a line every $MCDN_LOG_PROGRESS_SECONDS (default 10) of a long
        // stage, none for a short one; the stage's own line with its time ends it.
        const char* every = std::getenv("MCDN_LOG_PROGRESS_SECONDS");
        double seconds = 10;
        if (every && !mcdn::parse_finite(every, seconds))
            seconds = 10;
        struct Since {
            std::string stage;
            OIIO::Timer timer;
        };
        auto since = std::make_shared<Since>();
        return [since, seconds](const std::string& stage, float fraction) {
            if (stage != since->stage) {
                since->stage = stage;
                since->timer.reset();
                since->timer.start();
            } else if (fraction < 1 && since->timer() >= seconds) {
                std::fprintf(stderr, "mcdntool: %s %d%%\n", stage.c_str(), int(100 * fraction));
                std::fflush(stderr);
                since->timer.reset();
                since->timer.start();
            }
            return false;
        };
    }
    return [](const std::string& stage, float fraction) {
        // One line, rewritten in place and cleared when the stage is done.
        std::fprintf(stderr, "\rmcdntool: %s %3d%%\033[K", stage.c_str(), int(100 * fraction));
        if (fraction >= 1)
            std::fputs("\r\033[K", stderr);
        std::fflush(stderr);
        return false;
    };
}

void Session::capture_input_features(const std::vector<Queued>& stages)
{
    // Once, from the current image: the first prefilter has not run on it yet.
    const bool queued = std::any_of(stages.begin(), stages.end(), [](const Queued& q) {
        return mcdn::find_stage(q.name)->changes_features;
    });
    if (!queued || m_input_features.initialized())
        return;
    m_feature_names = mcdn::feature_channel_names(m_aovs, m_image.spec());
    std::vector<int> order;
    for (const std::string& name : m_feature_names)
        order.push_back(m_image.spec().channelindex(name));
    if (!order.empty())
        m_input_features =
            OIIO::ImageBufAlgo::channels(m_image, int(order.size()), order, {}, m_feature_names);
}

bool Session::restore_input_features(std::string& error)
{
    if (!prefilters || features_out || !m_input_features.initialized())
        return true;
    if (!mcdn::copy_channels_by_name(m_image, m_input_features, m_feature_names, error)) {
        error = "putting back the input's features: " + error;
        return false;
    }
    return true;
}

bool Session::take_denoiser_chain(mcdn::Denoiser& chain, int& chain_radius, ImageBuf& chain_input,
                                  std::string& error)
{
    if (!load_inputs(error))
        return false;
    std::vector<Queued> stages = m_applied;
    stages.insert(stages.end(), m_queue.begin(), m_queue.end());
    if (stages.empty()) {
        error = "--sure needs a denoiser before it to estimate the error of (e.g. --nfor --sure)";
        return false;
    }
    if (m_applied.empty())
        capture_input_features(stages);
    // Moved out, not copied: the caller's result replaces the current image, which SURE
    // recomputes anyway (y = F(x)).
    chain_input = std::move(m_applied.empty() ? m_image : m_chain_input);
    m_image = ImageBuf();
    m_queue.clear();
    std::vector<std::pair<std::string, mcdn::Denoiser>> denoisers;
    std::vector<mcdn::StageReach> reach;
    for (const auto& stage : stages)
        reach.push_back(stage.reach);
    chain_radius = mcdn::chain_radius(reach);
    for (const auto& stage : stages)
        denoisers.emplace_back(
            stage.name, [op = stage.op, threads = nthreads](ImageBuf& dst, const ImageBuf& src) {
                return op(dst, src, threads);
            });
    chain = mcdn::compose(std::move(denoisers));
    return true;
}

void report_repaired_halves(int tiles)
{
    if (tiles > 0)
        std::cerr << format("mcdntool: {} tile(s) of {}x{} pixels: the half buffers disagree "
                            "with the render there (a corrupt block?); their halves are the "
                            "render's colour\n",
                            tiles, mcdn::kConvergedTileSize, mcdn::kConvergedTileSize);
}

void report_fallback(const OIIO::ImageSpec& result, const std::string& stage)
{
    for (const auto& [stage, attribute, estimate] :
         { std::tuple { "nfor", mcdn::kNforFallbackCountAttribute, "NFOR's own MSE estimate" },
           std::tuple { "sure", mcdn::kSureFallbackCountAttribute, "SURE" } })
        if (const int tiles = result.get_int_attribute(attribute, 0); tiles > 0)
            std::cerr << format("mcdntool: {}: {} tile(s) of {}x{} pixels are the render: {} "
                                "says the denoiser made them worse (safety net; --{}:fallback=0 "
                                "turns it off, fallback-aov=1 shows where)\n",
                                stage, tiles, mcdn::kConvergedTileSize, mcdn::kConvergedTileSize,
                                estimate, stage);
    // A later stage keeps choose's attribute: said once, by choose (or for the bands).
    if ((stage.empty() || stage == "choose") && result.find_attribute(mcdn::kChooseShareAttribute))
        std::cerr << format("mcdntool: choose: the second denoiser's weight (with=) averages "
                            "{:.0f}% over the frame (the rest is the one's before --sure), "
                            "weighed by {}\n",
                            100.0f * result.get_float_attribute(mcdn::kChooseShareAttribute),
                            result.get_string_attribute(mcdn::kChooseEstimateAttribute, "SURE"));
    if (const int tiles = result.get_int_attribute(mcdn::kSureWorseCountAttribute, 0); tiles > 0)
        std::cerr << format("mcdntool: sure: SURE says the denoiser made {} tile(s) of {}x{} "
                            "pixels worse than the render (kept; --sure:fallback=1 makes them "
                            "the render, fallback-aov=1 shows where)\n",
                            tiles, mcdn::kConvergedTileSize, mcdn::kConvergedTileSize);
}

bool Session::apply(const std::string& name, const StageOp& op, std::string& error)
{
    if (!load(error))
        return false;
    return apply_to(name, m_image, op, error);
}

bool Session::apply_to(const std::string& name, const ImageBuf& input, const StageOp& op,
                       std::string& error)
{
    OIIO::Timer timer;
    ImageBuf result;
    if (!op(result, input, nthreads)) {
        error = result.geterror();
        return false;
    }
    if (verbose) {
        std::cerr << format("mcdntool: {} {}x{} done in {:.2f} s\n", name, result.spec().width,
                            result.spec().height, timer());
        report_fallback(result.spec(), name);
    }
    m_applied.clear();  // the current image is no longer what the chain made from its input
    return replace_image(std::move(result), error);
}

bool Session::read_neighbours(int radius, std::vector<std::shared_ptr<ImageBuf>>& previous,
                              std::vector<std::shared_ptr<ImageBuf>>& next,
                              std::string& error) const
{
    mcdn::InputSelection select = selection;
    select.aovs = aov_spec;
    for (int side : { -1, 1 }) {
        std::vector<std::shared_ptr<ImageBuf>>& frames = side < 0 ? previous : next;
        for (int k = 1; k <= radius; ++k) {
            std::vector<mcdn::InputFile> files;
            if (!neighbour_inputs || !neighbour_inputs(side * k, files)) {
                if (verbose)
                    std::cerr << format(
                        "mcdntool: cross-frame: {} (its files do not exist): {} {} of {}\n",
                        frame >= 0 ? format("no frame {} ({:+d})", frame + side * k, side * k)
                                   : format("no frame {:+d}", side * k),
                        k - 1, side < 0 ? "previous" : "next", radius);
                break;
            }
            auto frame = std::make_shared<ImageBuf>();
            mcdn::AovSet aovs;
            if (!mcdn::read_inputs(*frame, files, select)) {
                error = frame->geterror();
                return false;
            }
            int fixed = 0;
            if (!mcdn::resolve_aovs(aovs, aov_spec, frame->spec(), error)
                || !repair_and_check(*frame, aovs, fixed, error))
                return false;
            if (verbose) {
                if (!mcdn::frames_have_measured_variance(aovs))
                    say_once("mcdntool: cross-frame: no colour variance or halves: the frames "
                             "are weighed by how well they agree with each other\n");
            }
            frames.push_back(std::move(frame));
        }
    }
    return true;
}

bool Session::repair_and_check(ImageBuf& image, const mcdn::AovSet& aovs, int& fixed,
                               std::string& error) const
{
    mcdn::InputChecks checks;
    fixed = 0;
    if ((input_fix && !fix_non_finite(image, *input_fix, input_fix_name, nthreads, fixed, error))
        || !checks.check(image, aovs, error))
        return false;
    if (verbose)
        report_repaired_halves(checks.repaired_tiles());
    return true;
}

bool Session::load_inputs(std::string& error)
{
    if (m_loaded)
        return true;
    mcdn::InputRows rows;
    ImageBuf merged;
    if (!open_rows(rows, error)
        || !rows.read(merged, rows.spec().y, rows.spec().y + rows.spec().height, error))
        return false;
    if (!repair_and_check(merged, m_aovs, input_fixed, error))
        return false;
    m_image = std::move(merged);
    m_loaded = true;
    return true;
}

bool Session::open_rows(mcdn::InputRows& rows, std::string& error)
{
    mcdn::InputSelection select = selection;
    select.aovs = aov_spec;
    if (!rows.open(inputs, select, error))
        return false;
    const OIIO::ImageSpec& spec = rows.spec();
    if (!mcdn::resolve_aovs(m_aovs, aov_spec, spec, error))
        return false;
    if (!m_aovs.require({ Role::Color }, spec, error))
        return false;
    std::string colorspace, colorspace_why;
    if (!mcdn::input_colorspace(colorspace, colorspace_why, aov_spec, spec, error)) {
        error = inputs[0].path + ": " + error;
        return false;
    }
    if (verbose) {
        say_once(format("mcdntool: colour space '{}' ({}); the stages run in '{}'\n", colorspace,
                        colorspace_why, mcdn::working_colorspace()));
        say_once(format("mcdntool: AOV preset '{}'{}\n", m_aovs.preset(),
                        m_aovs.detected_because().empty()
                            ? std::string()
                            : " (detected: " + m_aovs.detected_because() + ")"));
        if (m_aovs.grey())
            say_once(format("mcdntool: luminance only ({}): denoised as grey\n",
                            m_aovs.names(Role::Color)[0]));
    }
    // The stages after this one resolve the same preset, whatever channels they add.
    if (aov_spec.preset.empty())
        aov_spec.preset = m_aovs.preset();
    if (verbose) {
        // What the stages will have to work with: a missing pass changes what runs.
        std::vector<std::string> found, missing;
        for (Role r :
             { Role::Albedo, Role::Normal, Role::Depth, Role::DiffuseColor, Role::GlossyColor })
            (m_aovs.has(r) ? found : missing).push_back(mcdn::role_name(r));
        say_once(format("mcdntool: features found: {}; missing: {}{}\n",
                        found.empty() ? "none" : Strutil::join(found, ", "),
                        missing.empty() ? "none" : Strutil::join(missing, ", "),
                        missing.empty() ? ""
                                        : " (nfor and prefilter leave them out, the "
                                          "cnn reads them as zeros)"));
        // The light groups and passes the denoisers take along (docs/aovs.md).
        std::vector<std::string> extras;
        for (const mcdn::AovSet::Extra& extra : m_aovs.extras())
            extras.push_back(extra.name.substr(extra.name.rfind('.') + 1));
        if (!extras.empty() && extras_denoised)
            say_once(format("mcdntool: denoised with the beauty: {} (extras=0 keeps them as "
                            "rendered)\n",
                            Strutil::join(extras, ", ")));
        else if (!extras.empty())
            say_once(format("mcdntool: kept as rendered: {} (no stage here denoises extra "
                            "AOVs, or extras=0)\n",
                            Strutil::join(extras, ", ")));
    }
    return true;
}

bool Session::switch_layer(const std::string& layer, std::string& error)
{
    if (!load(error) || !restore_input_features(error))
        return false;
    m_input_features = ImageBuf();
    m_feature_names.clear();
    m_applied.clear();
    m_chain_input = ImageBuf();
    aov_spec.layer = layer;
    // load() checked the first layer's values: this one's are checked here.
    return mcdn::resolve_aovs(m_aovs, aov_spec, m_image.spec(), error)
           && mcdn::validate_inputs(m_image, m_aovs, error);
}

bool Session::replace_image(ImageBuf result, std::string& error)
{
    m_image = std::move(result);
    return mcdn::resolve_aovs(m_aovs, aov_spec, m_image.spec(), error);
}

}  // namespace mcdntool
