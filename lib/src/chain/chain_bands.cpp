// A chain in bands of rows (mcdn/chain.h): the whole frame's statistics first (a light pass:
// core/frame_facts.h), then every stage of the chain on one band at a time, its halo the
// chain's reach, each band's own rows handed on. Every stage computes on a band what it
// would on the whole frame: the frame's statistics travel on the band's spec, random probes
// are drawn by the pixel's index in the frame, and bands start on the converged-tile grid.
#include "mcdn/chain.h"

#include <algorithm>
#include <cstdlib>
#include <memory>

#include <OpenImageIO/strutil.h>

#include "chain/chain_steps.h"
#include "cnn/cnn_steps.h"
#include "ops/bands.h"
#include "core/channels.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/trace.h"
#include "mcdn/choose.h"
#include "mcdn/cnn.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/skip.h"
#include "mcdn/settings.h"
#include "mcdn/stages.h"
#include "mcdn/sure.h"
#include "sure/sure_steps.h"

namespace mcdn {

namespace {

// The stages the chain runs: "denoise" is planned here, once for the frame.
bool resolved_stages(std::vector<std::string>& stages, const ImageSpec& spec, const ChainOptions& o,
                     std::string& error)
{
    ChainOptions planned;
    if (!planned_chain(planned, spec, o, error))
        return false;
    stages = planned.stages;
    return true;
}

// The frame's facts (core/frame_facts.h), from its rows read top to bottom: the whole
// frame at once or a band at a time gives the same facts. Only those the chain's stages
// read: the colour's sums (nfor's probe step and outlier rule, sure's probe step, the
// t-test's sigma_s), the depth range (cnn), the constant features and extras (prefilter,
// nfor), so that a cnn chain's pass need not decode the half files.
class LightPass {
public:
    LightPass(const ImageSpec& spec, const AovSet& aovs, const ChainOptions& o,
              const std::vector<std::string>& stages)
        : m_aovs(aovs), m_ybegin(spec.y), m_yend(spec.y + spec.height)
    {
        StageFacts facts;
        for (const std::string& name : stages)
            if (const StageInfo* stage = find_stage(name)) {
                facts.color_sums |= stage->facts.color_sums;
                facts.depth_range |= stage->facts.depth_range;
                facts.constant_features |= stage->facts.constant_features;
                facts.exposure |= stage->facts.exposure;
            }
        m_needs_color = facts.color_sums && aovs.channels(Role::Color).size() == 3;
        m_needs_depth = facts.depth_range;
        m_needs_constants = facts.constant_features;
        if (facts.exposure && aovs.channels(Role::Color).size() == 3)
            m_exposure = std::make_unique<Autoexposure>(spec.width, spec.height);
        m_reads.assign(size_t(spec.nchannels), false);
        if (m_needs_color || m_exposure)
            for (Role r : { Role::Color, Role::ColorVariance })
                for (int c : aovs.channels(r))
                    m_reads[size_t(c)] = true;
        if (m_needs_depth)
            for (int c : aovs.channels(Role::Depth))
                m_reads[size_t(c)] = true;
        if (!m_needs_constants)
            return;
        // Which feature channels (every face of albedo, normal, depth, visibility, and any
        // channel a stage's features= names) and extra AOV channels hold one sanitized value
        // over the frame.
        m_names = feature_channel_names(aovs, spec);
        // The extras' means and halves too: an empty one is left out (core/extra_aovs.h).
        for (const AovSet::Extra& extra : aovs.extras())
            for (const std::vector<int>* channels :
                 { &extra.channels, &extra.half_a, &extra.half_b })
                for (int ch : *channels)
                    m_names.push_back(spec.channel_name(ch));
        for (const StageInfo& stage : stage_table())  // a stage's extra features= channels
            if (auto it = o.settings.find(stage.name + ".features"); it != o.settings.end())
                for (const std::string& name : OIIO::Strutil::splits(it->second, ","))
                    for (const std::string& face :
                         { name, "variance." + name, "A." + name, "B." + name })
                        if (spec.channelindex(face) >= 0)
                            m_names.push_back(face);
        for (const std::string& name : m_names)
            m_channels.push_back(spec.channelindex(name));
        m_first.resize(m_names.size());
        m_constant.assign(m_names.size(), 1);
        for (int c : m_channels)
            m_reads[size_t(c)] = true;
    }

    /// The channels add() looks at (InputRows::read's `channels`).
    const std::vector<bool>& channels() const { return m_reads; }

    /// The next rows of the frame, in the working space.
    void add(const ImageBuf& rows)
    {
        const std::vector<int>& variance = m_aovs.channels(Role::ColorVariance);
        if (m_needs_color)
            add_color_sums(m_color, rows, m_aovs.channels(Role::Color).data(),
                           variance.size() == 3 ? variance.data() : nullptr);
        if (m_needs_depth && m_aovs.has(Role::Depth)) {
            const kpcn::DepthRange depth = kpcn::depth_range(rows, m_aovs);
            m_depth_lo = std::min(m_depth_lo, depth.lo);
            m_depth_hi = std::max(m_depth_hi, depth.hi);
        }
        if (m_needs_constants)
            add_constants(rows);
        if (m_exposure)
            m_exposure->add_rows(rows, m_aovs.channels(Role::Color).data(),
                                 rows.spec().y - m_ybegin);
        m_started = true;
    }

    FrameFacts facts() const
    {
        FrameFacts facts;
        facts.ybegin = m_ybegin;
        facts.yend = m_yend;
        if (m_needs_color)
            facts.color = combined(m_color);
        facts.has_depth = m_needs_depth;
        if (m_needs_depth && m_aovs.has(Role::Depth)) {
            facts.depth_lo = m_depth_lo;
            facts.depth_span = m_depth_hi - m_depth_lo;
        }
        facts.has_exposure = m_exposure != nullptr;
        facts.exposure = m_exposure ? m_exposure->scale() : 1.0f;
        facts.has_constant = m_needs_constants;
        for (size_t f = 0; f < m_names.size(); ++f)
            if (m_constant[f])
                facts.constant[m_names[f]] = m_first[f];
        return facts;
    }

private:
    // One pass over the rows, every channel at once (a channel at a time would stride
    // through all of them once per channel).
    void add_constants(const ImageBuf& src)
    {
        const ROI whole = src.roi();
        const int nch = src.spec().nchannels, nf = int(m_channels.size());
        std::vector<float> rows;
        const int rows_per_read = std::max(
            1, int((int64_t(1) << 22) / std::max<int64_t>(1, int64_t(whole.width()) * nch)));
        for (int y = whole.ybegin; y < whole.yend && nf > 0; y += rows_per_read) {
            ROI r = whole;
            r.ybegin = y;
            r.yend = std::min(y + rows_per_read, whole.yend);
            r.chbegin = 0;
            r.chend = nch;
            rows.resize(size_t(r.npixels()) * nch);
            src.get_pixels(r, OIIO::TypeDesc::FLOAT, rows.data());
            if (!m_started && y == whole.ybegin)
                for (int f = 0; f < nf; ++f)
                    m_first[f] = sanitize(rows[size_t(m_channels[f])]);
            for (int f = 0; f < nf; ++f) {
                if (!m_constant[f])
                    continue;
                const float* v = rows.data() + m_channels[f];
                const float value = m_first[f];
                bool same = true;
                for (size_t p = 0; p < size_t(r.npixels()) && same; ++p)
                    same = sanitize(v[p * nch]) == value;
                m_constant[f] = same;
            }
        }
    }

    const AovSet& m_aovs;
    int m_ybegin, m_yend;
    std::vector<std::string> m_names;
    std::vector<int> m_channels;
    std::vector<float> m_first;
    std::vector<char> m_constant;
    std::vector<bool> m_reads;
    ColorSums m_color[3];
    float m_depth_lo = INFINITY, m_depth_hi = -INFINITY;
    bool m_needs_color = false, m_needs_depth = false, m_needs_constants = false;
    std::unique_ptr<Autoexposure> m_exposure;  // only when a stage reads it
    bool m_started = false;
};

}  // namespace

int chain_reach(const ImageSpec& spec, const ChainOptions& given)
{
    ChainOptions o;
    std::string error;
    if (!planned_chain(o, spec, given, error))
        return -1;
    const std::vector<std::string>& stages = o.stages;
    // Each stage's reach; chain_radius knows that nfor reaches less after a prefilter.
    std::vector<StageReach> reaches;
    std::string denoiser = "nfor";  // a mix with no denoiser before it: mix.mcdnw's reach
    for (const std::string& name : stages) {
        const StageInfo* stage = find_stage(name);
        if (!stage)
            return -1;
        const Settings settings = stage_settings(o.settings, name);
        // Without a reach of its own (sure) a stage reaches no further than its denoisers.
        reaches.push_back(stage->reach ? stage->reach(settings, denoiser)
                                       : StageReach { 0, 0, false });
        if (stage->kind == StageKind::Denoiser && !stage->changes_features)
            denoiser = name;  // the prefilter filters the features, not the colour
    }
    return chain_radius(reaches);
}

namespace {

// The rows the light pass reads at a time: whole converged tiles (mcdn/skip.h), as the
// reader's counts of them expect (mcdntool counts the tiles of each read's rows).
constexpr int kLightPassRows = 8 * kConvergedTileSize;

// Sure's channels when the chain's sure probes the cnn alone (run_stages), else none.
std::vector<std::string> sure_room(const ImageSpec& frame, const ChainOptions& o)
{
    std::vector<std::string> stages;
    std::string error;
    AovSet aovs;
    SureOptions s;
    auto is = [&](size_t i, auto property) {
        const StageInfo* stage = i < stages.size() ? find_stage(stages[i]) : nullptr;
        return stage && property(*stage);
    };
    if (!resolved_stages(stages, frame, o, error)
        || !is(0, [](const StageInfo& s) { return s.probes_in_place; })
        || !is(1, [](const StageInfo& s) { return s.kind == StageKind::Estimator; })
        || !resolve_aovs(aovs, o.aovs, frame, error)
        || !apply_settings(s, stage_settings(o.settings, stages[1]), error))
        return {};
    std::vector<std::string> room;
    for (const std::string& name : sure_channel_names(aovs, s))
        if (frame.channelindex(name) < 0)
            room.push_back(name);
    return room;
}

// A zeroed frame of `frame`'s channels and `room` after them, rows [y0, y1): what a
// RowReader reads into, leaving the room as it is.
bool allocate_with_room(ImageBuf& dst, const ImageSpec& frame, const std::vector<std::string>& room,
                        int y0, int y1, std::string& error)
{
    ImageSpec spec = frame;
    spec.y = y0;
    spec.height = y1 - y0;
    for (const std::string& name : room)
        spec.channelnames.push_back(name);
    spec.nchannels = int(spec.channelnames.size());
    if (allocate_frame(dst, spec, true))
        return true;
    error = "chain: " + dst.geterror();
    return false;
}

// The bands of a frame through the chain, once the frame's facts are known: `rows` gives a
// band's rows (its cut), every channel, in the working space; with `convert`, converted
// there from `from` (each result goes back).
bool run_bands(const std::vector<Band>& bands, const ROI& whole, const FrameFacts& facts,
               const std::function<bool(ImageBuf&, const Band&, std::string&)>& rows,
               const std::string& from, bool convert, const ChainOptions& o, const BandSink& sink,
               std::string& error, int nthreads)
{
    StageTrace trace("chain");
    ChainOptions band_options = o;
    band_options.band_pixels = 0;
    for (size_t b = 0; b < bands.size(); ++b) {
        if (o.progress)
            band_options.progress = [&o, b, n = bands.size()](const std::string& stage,
                                                              float fraction) {
                return o.progress(stage, (float(b) + fraction) / float(n));
            };
        ImageBuf band, result;
        if (!rows(band, bands[b], error))
            return false;
        set_frame_facts(band.specmod(), facts);
        if (!run_chain_on_own(result, band, band_options, nthreads)) {
            error = result.geterror();
            return false;
        }
        band.reset();
        result.specmod().erase_attribute(kFrameFactsAttribute);
        if (convert) {
            AovSet result_aovs;
            if (!resolve_aovs(result_aovs, o.aovs, result.spec(), error)
                || !out_of_working_space(result, result_aovs, from, error, nthreads))
                return false;
        }
        ROI own = whole;
        own.ybegin = bands[b].own_begin;
        own.yend = bands[b].own_end;
        if (!sink(result, own, error))
            return false;
        trace.mark("band: stages and its rows out");
    }
    return true;
}

}  // namespace

namespace {

// BandCounts' tile counts, in the order of its tiles_.
constexpr const char* kCounted[] = { kNforFallbackCountAttribute, kSureFallbackCountAttribute,
                                     kSureWorseCountAttribute };

}  // namespace

void BandCounts::add(const ImageSpec& band)
{
    static_assert(sizeof(tiles_) / sizeof(tiles_[0]) == std::size(kCounted));
    for (size_t i = 0; i < std::size(kCounted); ++i)
        tiles_[i] += band.get_int_attribute(kCounted[i], 0);
    if (band.find_attribute(kChooseShareAttribute)) {
        const double pixels = double(band.image_pixels());
        share_sum_ += band.get_float_attribute(kChooseShareAttribute) * pixels;
        share_pixels_ += pixels;
    }
    if (band.find_attribute(kChooseEstimateAttribute))
        estimate_ = band.get_string_attribute(kChooseEstimateAttribute);
}

void BandCounts::set(ImageSpec& frame) const
{
    for (size_t i = 0; i < std::size(kCounted); ++i) {
        frame.erase_attribute(kCounted[i]);
        if (tiles_[i] > 0)
            frame.attribute(kCounted[i], int(std::min<int64_t>(tiles_[i], INT32_MAX)));
    }
    frame.erase_attribute(kChooseShareAttribute);
    if (share_pixels_ > 0)
        frame.attribute(kChooseShareAttribute, float(share_sum_ / share_pixels_));
    frame.erase_attribute(kChooseEstimateAttribute);
    if (!estimate_.empty())
        frame.attribute(kChooseEstimateAttribute, estimate_);
}

void set_bands_from_environment(ChainOptions& options)
{
    const char* text = std::getenv("MCDN_BAND_PIXELS");
    if (!text || !*text)
        return;
    char* end = nullptr;
    const long long pixels = std::strtoll(text, &end, 10);
    if (*end || pixels < 0)
        return;
    options.band_pixels = pixels;
    options.band_halos = 0;  // exactly the bands asked for
}

ChainBand chain_band(int width, const ChainOptions& o, int reach)
{
    ChainBand band;
    band.halo_rows =
        (std::max(reach, 0) + kConvergedTileSize - 1) / kConvergedTileSize * kConvergedTileSize;
    band.own_pixels = o.band_pixels <= 0 || o.band_halos <= 0
                          ? o.band_pixels
                          : std::max(o.band_pixels, int64_t(o.band_halos) * band.halo_rows * width);
    return band;
}

namespace {

// The chain's bands of `spec`'s frame; one band: the whole frame at once.
std::vector<Band> chain_bands(const ImageSpec& spec, const ChainOptions& o)
{
    const int reach = chain_reach(spec, o);
    // A band of a larger frame (it carries the frame's facts) is never cut again.
    return reach >= 0 && !is_frame_band(spec)
               ? plan_bands(spec.roi(), reach, chain_band(spec.width, o, reach).own_pixels)
               : plan_bands(spec.roi(), 0, 0);
}

// A frame of one band: the chain on the whole of it, handed on at once. `own`: input
// itself, when it is ours (read for the chain), else null.

bool run_whole(const ImageBuf& input, ImageBuf* own, const ChainOptions& o, const BandSink& sink,
               std::string& error, int nthreads)
{
    const ROI whole = input.roi();  // before the chain: it may release its own input
    ImageBuf result;
    ChainOptions whole_frame = o;
    whole_frame.band_pixels = 0;
    if (!(own ? run_chain_on_own(result, *own, whole_frame, nthreads)
              : run_chain(result, input, whole_frame, {}, nthreads))) {
        error = result.geterror();
        return false;
    }
    return sink(result, whole, error);
}

// The input's colour space and the frame's resolved AOVs, for a chain in bands.
bool band_setup(std::string& from, AovSet& aovs, const ImageSpec& spec, const ChainOptions& o,
                std::string& error)
{
    std::string why;
    if (!input_colorspace(from, why, o.aovs, spec, error)) {
        error = "chain: " + error;
        return false;
    }
    return resolve_aovs(aovs, o.aovs, spec, error);
}

}  // namespace

bool run_chain(const ImageBuf& input, const ChainOptions& o, const BandSink& sink,
               std::string& error, int nthreads)
{
    const ROI whole = input.roi();
    const std::vector<Band> bands = chain_bands(input.spec(), o);
    if (bands.size() == 1)
        return run_whole(input, nullptr, o, sink, error, nthreads);
    // The light pass and the bands in the working space (the stages then convert nothing);
    // each band's result back in the input's space before it is handed on.
    std::string from;
    AovSet aovs;
    if (!band_setup(from, aovs, input.spec(), o, error))
        return false;
    const bool convert = needs_working_conversion(input.spec(), from, aovs);
    ImageBuf converted;
    if (convert) {
        converted = input.copy(OIIO::TypeDesc::FLOAT);
        if (!into_working_space(converted, aovs, from, error, nthreads))
            return false;
    }
    const ImageBuf& src = convert ? converted : input;
    StageTrace trace("chain");
    trace.mark("(before the chain)");
    std::vector<std::string> stages;
    if (!resolved_stages(stages, src.spec(), o, error))
        return false;
    LightPass light(src.spec(), aovs, o, stages);
    light.add(src);
    const FrameFacts facts = light.facts();
    trace.mark("light pass (frame facts)");
    // Rows of src, every channel, as a float buffer of their own.
    auto rows = [&](ImageBuf& band, const Band& cut, std::string&) {
        band = copy_with_channels(src, {}, cut.cut, nthreads);
        return true;
    };
    return run_bands(bands, whole, facts, rows, from, convert, o, sink, error, nthreads);
}

bool run_chain(const ImageSpec& frame, const RowReader& read, const ChainOptions& o,
               const BandSink& sink, std::string& error, int nthreads)
{
    const ROI whole = frame.roi();
    const std::vector<Band> bands = chain_bands(frame, o);
    if (bands.size() == 1) {  // read whole, run whole
        ImageBuf input;
        // A sure that probes the cnn alone makes its result in the input itself when the
        // input has room for its channels (SureOptions::denoiser_in_place): read into a
        // frame that has them, zero, after the frame's own.
        const std::vector<std::string> room = sure_room(frame, o);
        if (!room.empty()
            && !allocate_with_room(input, frame, room, whole.ybegin, whole.yend, error))
            return false;
        return read(input, whole.ybegin, whole.yend, {}, error)
               && run_whole(input, &input, o, sink, error, nthreads);
    }
    std::string from;
    AovSet aovs;
    if (!band_setup(from, aovs, frame, o, error))
        return false;
    const bool convert = needs_working_conversion(frame, from, aovs);
    // Rows [y0, y1) in the working space: what the chain on a buffer sees.
    auto read_working = [&](ImageBuf& rows, int y0, int y1, const std::vector<bool>& channels,
                            std::string& error) {
        if (!read(rows, y0, y1, channels, error))
            return false;
        if (convert) {
            if (!into_working_space(rows, aovs, from, error, nthreads))
                return false;
        }
        return true;
    };
    StageTrace trace("chain");
    trace.mark("(before the chain)");
    // The light pass reads the frame kLightPassRows at a time, top to bottom, only the
    // channels it looks at (the files of the others are not decoded). Its facts do not
    // depend on where the reads cut the rows; its buffer holds every channel, so a band's
    // rows at a time made it a third of the bands' peak at 8K, left in the heap's way.
    std::vector<std::string> stages;
    if (!resolved_stages(stages, frame, o, error))
        return false;
    LightPass light(frame, aovs, o, stages);
    ImageBuf light_rows;  // read into again: one read's pages for the pass
    for (int y0 = whole.ybegin; y0 < whole.yend; y0 += kLightPassRows) {
        const int y1 = std::min(whole.yend, y0 + kLightPassRows);
        if (!read_working(light_rows, y0, y1, light.channels(), error))
            return false;
        light.add(light_rows);
    }
    light_rows.reset();
    const FrameFacts facts = light.facts();
    trace.mark("light pass (frame facts)");
    // Each band read with sure's room, as the whole frame above: sure then probes the
    // denoiser in the band itself, not in a copy of it (8K --denoise: 2.8 GB a band).
    const std::vector<std::string> room = sure_room(frame, o);
    auto rows = [&](ImageBuf& band, const Band& cut, std::string& error) {
        if (!room.empty()
            && !allocate_with_room(band, frame, room, cut.cut.ybegin, cut.cut.yend, error))
            return false;
        return read_working(band, cut.cut.ybegin, cut.cut.yend, {}, error);
    };
    return run_bands(bands, whole, facts, rows, from, convert, o, sink, error, nthreads);
}

}  // namespace mcdn
