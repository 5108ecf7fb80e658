// The stage table (mcdn/stages.h): one entry per stage. An entry's functions turn settings
// into the stage's Options (mcdn/settings.h) and the Options into a Denoiser-shaped op.
// Here NFOR's and the networks' entries and the table; Progressive Denoising's (sure,
// choose, mix) in stage_table_pd.cpp; what both share in stage_entries.h.
#include "mcdn/stages.h"

#include <algorithm>

#include "mcdn/cnn.h"
#include "mcdn/frames.h"
#include "mcdn/nfor.h"
#include "mcdn/oidn.h"
#include "mcdn/prefilter.h"
#include "chain/settings_reader.h"
#include "chain/stage_entries.h"

namespace mcdn {
namespace stage_entries {

// A denoiser of one frame, cross-frame when the context has neighbours: the frames combined
// where they agree (mcdn/frames.h), then the denoiser; both are the denoiser (SURE probes
// this frame through both).
Denoiser across_frames(Denoiser denoiser, const StageContext& context)
{
    if (context.previous_frames.empty() && context.next_frames.empty())
        return denoiser;
    CombineFramesOptions combine;
    combine.aovs = context.aovs;
    combine.previous_frames = context.previous_frames;
    combine.next_frames = context.next_frames;
    return [combine, denoiser, n = context.nthreads](ImageBuf& dst, const ImageBuf& src) {
        return denoise_with_frames(dst, src, combine, denoiser, n);
    };
}

// ---- prefilter (NFOR §5.1) ------------------------------------------------------------

bool make_prefilter(MadeStage& made, const Settings& settings, const StageContext& context,
                    std::string& error)
{
    PrefilterOptions o;
    if (!options_of(o, settings, context, error))
        return false;
    made.reach = stage_reach(o);
    made.run = [o, n = context.nthreads](ImageBuf& dst, const ImageBuf& src) {
        return prefilter(dst, src, o, {}, n);
    };
    return true;
}

bool prefilter_can_run(const AovSet& aovs, std::string& how)
{
    how = !has_features(aovs) ? "no albedo, normal, depth or visibility to filter"
          : has_halves(aovs)  ? "cross-filters the features' halves"
                              : "no half buffers: each feature by its own variance";
    return has_features(aovs);
}

StageInfo prefilter_stage()
{
    StageInfo s;
    s.name = "prefilter";
    s.keys = { "window", "patch", "k", "features", "features-out", "skip", "converged" };
    s.changes_features = true;
    s.reads_halves = with_any_settings;
    s.facts.constant_features = true;
    s.frame_buffers = 0.5;  // the prefiltered features beside the frame
    s.help = "NFOR feature prefilter (§5.1): NL-means cross-filtering of albedo, normal, depth "
             "and visibility with their half buffers. window=11 patch=7 k=0.5; features=a,b "
             "adds extra feature channels.";
    s.needs = "the features (albedo, normal, depth, visibility) with their half buffers "
              "(-i:as=halfA, -i:as=halfB) and variances; without halves each feature is "
              "filtered by its own variance.";
    s.check = check_settings<PrefilterOptions>;
    s.make = make_prefilter;
    s.reach = reach_of<PrefilterOptions>;
    s.can_run = prefilter_can_run;
    return s;
}

// ---- nfor (NFOR §5.2-5.4, §8) ---------------------------------------------------------

bool make_nfor(MadeStage& made, const Settings& settings, const StageContext& context,
               std::string& error)
{
    NforOptions o;
    if (!options_of(o, settings, context, error))
        return false;
    o.previous_frames = context.previous_frames;
    o.next_frames = context.next_frames;
    made.reach = stage_reach(o);
    made.run = [o, n = context.nthreads](ImageBuf& dst, const ImageBuf& src) {
        return nfor(dst, src, o, {}, n);
    };
    return true;
}

bool nfor_can_run(const AovSet& aovs, std::string& how)
{
    const bool variance = aovs.has(Role::ColorVariance);
    how = has_halves(aovs) ? "two-buffer (§5.2-5.4)"
          : variance       ? "one-buffer: no half buffers, SURE picks the bandwidth, no §5.4"
                           : "needs two half buffers or the colour's variance";
    return has_halves(aovs) || variance;
}

StageInfo nfor_stage()
{
    StageInfo s;
    s.name = "nfor";
    s.keys = { "window",   "patch",        "k",      "mse",      "selection",
               "features", "features-out", "halves", "extras",   "outliers",
               "fallback", "fallback-aov", "skip",   "converged" };
    s.cross_frame = true;
    s.reads_halves = with_any_settings;
    s.facts.color_sums = true;
    s.facts.constant_features = true;
    s.frame_buffers = 2.0;  // the result and the per-buffer regression outputs
    s.help = "NFOR denoiser (§5.2-5.4): first-order regression on the features, collaborative, "
             "bandwidth chosen per pixel. window=19 patch=7 k=0.5,1.0; mse=1 and selection=1 "
             "add nfor.mse.* and nfor.selection.* channels. Prefilters the features itself "
             "unless --prefilter ran. Extra AOVs (light groups, light passes such as "
             "Blender's DiffDir, extra.NAME) are denoised with the beauty's weights so they "
             "still add up (extras=0: keep them as they are). "
             "A pixel holding one sample worth a hundred of its neighbours (a caustic through "
             "glass, a firefly) is kept out of the regressions and its excess removed, as a "
             "sample clamp would (outliers=drop; keep: added back where it was; off: left in). "
             "Safety net (on; fallback=0: off): a 32x32 tile where NFOR's own MSE estimate is "
             "above the render's variance is the render, -v says how many (fallback-aov=1 adds "
             "channel nfor.fallback, 1 on those tiles). "
             "Cross-frame (§8), in a sequence: frames=2 fits over the 2 previous and 2 next "
             "frames too, aligned by the motion vectors (Blender's Vector pass, RenderMan's "
             "forward and backward); it reads them "
             "(also across --frames chunk edges), never writes them, and runs the whole frame.";
    s.needs = "the colour and its two half buffers (each the mean of half the samples: "
              "-i:as=halfA, -i:as=halfB; a Tungsten folder has them); the variance of the mean "
              "(else the halves' difference); features, prefiltered unless --prefilter ran. "
              "Without halves, render them, or use --denoise or --cnn.";
    s.check = check_settings<NforOptions>;
    s.make = make_nfor;
    s.reach = reach_of<NforOptions>;
    s.can_run = nfor_can_run;
    return s;
}

// ---- cnn (KPCN; cross-frame through mcdn/frames.h) -------------------------------------

bool make_cnn(MadeStage& made, const Settings& settings, const StageContext& context,
              std::string& error)
{
    CnnOptions o;
    if (!options_of(o, settings, context, error))
        return false;
    made.reach = stage_reach(o);
    made.run =
        across_frames([o, n = context.nthreads](
                          ImageBuf& dst, const ImageBuf& src) { return cnn(dst, src, o, {}, n); },
                      context);
    return true;
}

// Its network buffers (mcdn/cnn.h), a tile per worker thread: 350 MB a thread at tile=512,
// as (tile + halo)^2.
double cnn_held_bytes(const Settings& settings, int threads)
{
    CnnOptions o;
    std::string error;
    apply_settings(o, settings, error);
    const double side = (std::max(o.tile_size, 1) + 64) / double(512 + 64);
    return threads * 350e6 * side * side;
}

bool cnn_can_run(const AovSet& aovs, std::string& how)
{
    how = has_features(aovs) ? "with the features there are" : "no features: the CNN reads zeros";
    how += "; weights " + default_cnn_weights(&aovs);
    return true;
}

StageInfo cnn_stage()
{
    StageInfo s;
    s.name = "cnn";
    s.keys = { "weights", "tile", "extras", "outliers", "skip", "converged" };
    s.cross_frame = true;
    s.probes_in_place = true;
    s.reads_light_split = true;
    s.facts.depth_range = true;
    s.frame_buffers = 1.2;  // the result and the converged map
    s.held_bytes = cnn_held_bytes;
    s.help = "Kernel-predicting CNN denoiser (KPCN): diffuse/specular split, our trained weights "
             "(models/kpcn.mcdnw; on a render with neither a colour variance nor the light "
             "split, models/kpcn_can.mcdnw, trained on colour, albedo and normal alone; "
             "weights=FILE), tiled (tile=384). Extra AOVs take their share "
             "of the beauty's denoised light through its kernels (extras=0: keep them). A pixel "
             "holding one sample worth a hundred of its neighbours (a caustic through glass, a "
             "firefly) is taken out of the network's input and its excess removed, by --nfor's "
             "rule (outliers=drop; off: left in, where the kernels spread it). "
             "Cross-frame, in a sequence: frames=2 first combines this frame with 2 previous "
             "and 2 next ones, aligned by the motion vectors (Blender's Vector pass, RenderMan's "
             "forward and backward), weighted "
             "by how well their patches agree (by the colour's variance or halves, else by the "
             "frames' agreement with each other): a render of up to 5 times the samples where "
             "they do. It reads them (also across --frames chunk edges), never writes them.";
    s.needs = "the colour; the diffuse/specular split (Cycles' DiffCol/Dir/Ind and Gloss*, or "
              "diffuse.*, specular.*) where present; albedo, normal, depth and their variances "
              "(missing ones are zero: -v names them).";
    s.check = check_settings<CnnOptions>;
    s.make = make_cnn;
    s.reach = reach_of<CnnOptions>;
    s.can_run = cnn_can_run;
    return s;
}

// ---- oidn (Open Image Denoise's published networks, on our engine) ---------------------

bool oidn_settings(OidnOptions& o, const Settings& settings, std::string& error)
{
    return SettingsReader(settings, "oidn", error)
        .text("weights", o.weights)
        .positive_int("tile", o.tile_size)
        .flag("extras", o.denoise_extras)
        .drop_or_off("outliers", o.outliers)
        .flag("prefilter", o.prefilter)
        .skip(o.skip)
        .ok();
}

bool make_oidn(MadeStage& made, const Settings& settings, const StageContext& context,
               std::string& error)
{
    OidnOptions o;
    if (!oidn_settings(o, settings, error))
        return false;
    o.aovs = context.aovs;
    o.progress = context.progress;
    // No weights: said now, before any stage of the chain runs.
    const int r = receptive_radius(o);
    std::string path;
    if (r < 0 && !oidn_weights(path, o, true, true, error))
        return false;
    made.reach = { r, r, false };
    made.run =
        across_frames([o, n = context.nthreads](
                          ImageBuf& dst, const ImageBuf& src) { return oidn(dst, src, o, {}, n); },
                      context);
    return true;
}

// The network's buffers, one window at a time whatever the threads: the storage plan's
// slots (nn/net_plan.h) of OIDN's UNet as it runs, fused: 150.4 floats a pixel (173 for its
// unfused plan, 172.5 for tests/nn/plan_test's shape of it), over at most (tile + 2 halo)^2
// (nn::TileOptions::balanced); the halo is its receptive radius rounded up to its alignment,
// 112.
// Whether --oidn finds weights for some model (--denoise's plan then runs it: mcdn/denoise.h).
bool oidn_weights_found()
{
    std::string path, unused;
    return oidn_weights(path, OidnOptions(), true, true, unused)
           || oidn_weights(path, OidnOptions(), false, false, unused);
}

double oidn_held_bytes(const Settings& settings, int)
{
    OidnOptions o;
    std::string error;
    oidn_settings(o, settings, error);
    const double side = o.tile_size + 2 * 112;
    return side * side * 151 * sizeof(float);
}

StageInfo oidn_stage()
{
    StageInfo s;
    s.name = "oidn";
    s.keys = { "weights", "tile", "extras", "outliers", "prefilter", "skip", "converged" };
    s.cross_frame = true;
    s.probes_in_place = true;
    s.facts.exposure = true;
    s.frame_buffers = 1.0;  // the result
    s.held_bytes = oidn_held_bytes;
    s.help =
        "Intel Open Image Denoise's published network on our engine, with your copy of "
        "OIDN's weights (weights=FILE.tza or a folder of them; else $MCDN_OIDN_WEIGHTS, "
        "else <prefix>/share/mcdenoise/oidn/; mcdenoise does not ship them: they are "
        "OIDN's, Apache 2.0, from RenderKit/oidn-weights). The model follows the inputs: "
        "colour + albedo + normal (rt_hdr_alb_nrm), colour + albedo (rt_hdr_alb), colour "
        "(rt_hdr); prefilter=1 first cleans the albedo and normal with OIDN's networks for them "
        "(rt_alb, rt_nrm) and reads them with rt_hdr_calb_cnrm, as Blender's \"Accurate\" "
        "prefilter and OIDN's cleanAux do (two more networks' work a frame; better at high "
        "sample counts). Tiled (tile=1024), a tile at a time with every thread in it. "
        "Extra AOVs "
        "(light groups and passes) are denoised by "
        "the network too, each a run of its own, then shared so that extras that add up "
        "to the beauty still do (extras=0: keep them). A pixel holding one "
        "sample worth a hundred of its neighbours (a caustic, a firefly) enters the network "
        "as its neighbourhood and its excess is removed, by --nfor's rule (outliers=drop; "
        "off: left in, where the network spreads it). Cross-frame, in a "
        "sequence: frames=2 combines this frame with 2 previous and 2 next ones first, as "
        "--cnn:frames=2 does. "
        "--oidn --sure --mix is Progressive Denoising's configuration (§6): OIDN's result, "
        "its SURE, and the mix that converges to the render.";
    s.needs = "the colour; the albedo and normal where present (Cycles' Denoising Albedo and "
              "Denoising Normal, any preset's). --sure and --mix after it need the colour's "
              "variance.";
    s.check = [](const Settings& settings, std::string& error) {
        OidnOptions o;
        return oidn_settings(o, settings, error);
    };
    s.make = make_oidn;
    s.reads_all_variances = with_no_settings;  // the colour's, for its outlier rule
    s.reach = [](const Settings& settings, const std::string&) {
        OidnOptions o;
        std::string error;
        const int r = oidn_settings(o, settings, error) ? receptive_radius(o) : -1;
        return StageReach { r, r, false };
    };
    s.can_run = [](const AovSet& aovs, std::string& how) {
        const bool albedo = aovs.has(Role::Albedo), normal = aovs.has(Role::Normal);
        std::string path;
        if (!oidn_weights(path, OidnOptions(), albedo, normal, how)) {
            how = "no OIDN weights at " + path + " (weights=FILE, $MCDN_OIDN_WEIGHTS, or "
                  + oidn_weights_dir() + ")";
            return false;
        }
        how = path + " on "
              + (albedo && normal ? "colour, albedo and normal"
                 : albedo         ? "colour and albedo"
                                  : "the colour alone");
        return true;
    };
    return s;
}

// ---- the table ------------------------------------------------------------------------

StageInfo denoise_stage()
{
    StageInfo s;
    s.name = "denoise";
    s.kind = StageKind::Plan;
    s.cross_frame = true;
    s.keys = { "extras", "choose" };
    s.reads_light_split = true;
    // choose's NFOR beside the CNN, and the neighbours' agreement (frames=N), where the
    // render has them; with OIDN's weights (the CNN beside OIDN) neither runs.
    s.reads_halves = [](const Settings& settings) {
        const auto frames = settings.find("frames");
        return !oidn_weights_found() || (frames != settings.end() && frames->second != "0");
    };
    // With OIDN's weights and choose=0: oidn, sure, mix, which read the colour's variance
    // alone; the CNN (beside OIDN, or in its place) reads the features' too.
    s.reads_all_variances = [](const Settings& settings) {
        const auto choose = settings.find("choose"), frames = settings.find("frames");
        return !oidn_weights_found() || choose == settings.end() || choose->second != "0"
               || (frames != settings.end() && frames->second != "0");
    };
    s.help = "The best chain the inputs allow: with a colour variance --cnn --sure --mix "
             "(KPCN, its SURE, the progressive mix by the network: never much worse than the "
             "better of render and CNN), with half buffers too --choose before --mix (NFOR "
             "beside the CNN, per pixel by SURE), without a variance --cnn alone; with OIDN's "
             "weights where --oidn finds them, --oidn in the CNN's place, with a variance "
             "--oidn --sure --choose:with=cnn --mix (our CNN beside OIDN where the render is "
             "clean enough for SURE to tell them apart: at high sample counts). choose=0: no "
             "--choose, nor its cost; none with frames=N. -v prints which and why. "
             "To choose stages and their settings, name them instead. In a sequence, frames=2 "
             "is cross-frame: the CNN's input is this frame combined with 2 previous and 2 next "
             "ones where they agree (as --cnn:frames=2), against flicker: it needs the motion "
             "vectors (Blender's Vector pass, RenderMan's forward and backward), and weighs the "
             "agreement by the colour's variance "
             "or halves, else by how well the frames agree with each other (Cycles: tick Seed's "
             "animate, or frames of one seed bring nothing where nothing moves). Light groups and "
             "passes are denoised with the "
             "beauty (extras=0: keep them as rendered, and the time they cost).";
    s.needs = "the colour (any preset); with its variance (the renderer's variance AOV, a "
              "Tungsten folder; Cycles writes none: render K seeds, -i:as=seed each) the mixed "
              "chain; for frames=N the motion vectors. Albedo, normal and depth "
              "help the CNN; missing ones are zero (-v names them).";
    return s;
}

std::vector<StageInfo> make_table()
{
    std::vector<StageInfo> table = { denoise_stage(), prefilter_stage(), nfor_stage(),
                                     cnn_stage(),     oidn_stage(),      sure_stage(),
                                     choose_stage(),  mix_stage() };
    // The plan's memory is that of its longest chain (mcdn/denoise.h): cnn or oidn, sure,
    // choose, mix; besides, the larger of its denoisers' networks.
    for (const char* planned : { "cnn", "sure", "choose", "mix" }) {
        const auto& stage = *std::find_if(table.begin(), table.end(),
                                          [&](const StageInfo& s) { return s.name == planned; });
        table[0].frame_buffers += stage.frame_buffers;
    }
    table[0].held_bytes = [](const Settings& settings, int threads) {
        return std::max(cnn_held_bytes(settings, threads),
                        oidn_weights_found() ? oidn_held_bytes(settings, threads) : 0.0);
    };
    return table;
}

}  // namespace stage_entries

const std::vector<StageInfo>& stage_table()
{
    static const std::vector<StageInfo> table = stage_entries::make_table();
    return table;
}

InputSelection chain_input_selection(const std::vector<std::pair<std::string, Settings>>& stages,
                                     bool variance_given)
{
    InputSelection selection;
    selection.only_roles = true;
    selection.light_split = false;
    selection.halves = !variance_given;
    selection.all_variances = false;
    for (const auto& [name, settings] : stages) {
        const StageInfo* stage = find_stage(name);
        if (!stage)
            return InputSelection();
        selection.light_split |= stage->reads_light_split;
        selection.halves |= stage->reads_halves(settings);
        selection.all_variances |= stage->reads_all_variances(settings);
        if (const auto features = settings.find("features"); features != settings.end())
            for (const std::string& f : OIIO::Strutil::splits(features->second, ","))
                selection.extra_features.push_back(f);
    }
    return selection;
}

InputSelection chain_input_selection(const std::vector<std::string>& stages,
                                     const Settings& chain_settings, bool variance_given)
{
    std::vector<std::pair<std::string, Settings>> each;
    for (const std::string& name : stages)
        each.emplace_back(name, stage_settings(chain_settings, name));
    return chain_input_selection(each, variance_given);
}

const StageInfo* find_stage(const std::string& name)
{
    for (const StageInfo& stage : stage_table())
        if (stage.name == name
            || std::find(stage.aliases.begin(), stage.aliases.end(), name) != stage.aliases.end())
            return &stage;
    return nullptr;
}

std::vector<std::string> stage_names(std::initializer_list<StageKind> kinds)
{
    std::vector<std::string> names;
    for (const StageInfo& stage : stage_table())
        if (kinds.size() == 0 || std::find(kinds.begin(), kinds.end(), stage.kind) != kinds.end())
            names.push_back(stage.name);
    return names;
}

}  // namespace mcdn
