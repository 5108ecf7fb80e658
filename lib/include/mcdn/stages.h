// The stage table: every stage of the library, once (oiiotool's op table is the model).
// Each entry says what the stage is called, what kind of stage it is, which settings it
// takes and how they become its Options, how to make and run it, how far it reaches, what
// memory it adds, what it reads and what its help says. Every front end reads this table:
// run_chain and recipes (mcdn/chain.h), mcdntool's commands, --help, --info and memory
// check, Python's named denoisers, and denoise()'s plan. A new stage is one entry here
// (lib/src/chain/stage_table.cpp) and its own folder.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/io.h"
#include "mcdn/progress.h"
#include "mcdn/settings.h"

namespace mcdn {

/// What a stage is in a chain (mcdn/chain.h).
enum class StageKind {
    Denoiser,   ///< dst = F(src): what SURE estimates the error of and runs K + 1 times
    Estimator,  ///< sure: the error of the denoisers before it, as channels of its result
    Mixer,      ///< choose, mix: read what an Estimator before them wrote
    Plan,       ///< denoise: picks the whole chain itself from the inputs (mcdn/denoise.h)
};

/// What a front end hands a stage it makes.
struct StageContext {
    AovSpec aovs;
    ProgressCallback progress;
    int nthreads = 0;
    /// The region an Estimator or a Mixer computes (its op's roi); Denoisers run on all of
    /// their input, which SURE's probes reach into.
    ROI roi;
    /// A cross-frame stage's neighbouring frames, nearest first (StageInfo::cross_frame);
    /// the caller keeps them alive as long as the made stage.
    std::vector<const ImageBuf*> previous_frames, next_frames;
    /// An Estimator's denoiser: the Denoisers before it as one (compose_in_place), how far
    /// they reach (chain_radius) and whether they may run in the probed input itself
    /// (SureOptions::denoiser_in_place). A Mixer's: the last Estimator's denoiser (choose
    /// runs it on the halves), empty where none came before.
    Denoiser denoiser;
    int denoiser_radius = -1;
    bool denoiser_in_place = false;
};

/// A stage made from its settings.
struct MadeStage {
    /// dst = stage(src); dst may be src.
    Denoiser run;
    /// An Estimator on an input the caller gives up (sure_probing_src: probed in place, no
    /// frame-sized copy); null for other kinds.
    std::function<bool(ImageBuf& dst, ImageBuf& own)> run_on_own;
    StageReach reach;
};

/// The whole frame's facts a stage reads (the chain's light pass, core/frame_facts.h).
struct StageFacts {
    bool color_sums = false;         ///< the colour's sums (probe steps, the t-test's sigma_s)
    bool depth_range = false;        ///< the depth range (the CNN's depth normalisation)
    bool constant_features = false;  ///< which features and extras hold one value
    bool exposure = false;           ///< the colour's autoexposure (OIDN's networks)
};

/// StageInfo's predicates of the settings for a stage that does the thing with none of them,
/// and with any: reads_halves (NFOR and its prefilter read the halves with any settings),
/// reads_all_variances (OIDN, sure and the mix with none).
inline bool with_no_settings(const Settings&)
{
    return false;
}
inline bool with_any_settings(const Settings&)
{
    return true;
}

struct StageInfo {
    std::string name;                  ///< "nfor": chains, recipes, Python; mcdntool's --nfor
    std::vector<std::string> aliases;  ///< other names find_stage() accepts
    StageKind kind = StageKind::Denoiser;
    /// The settings it takes (mcdntool's modifiers, a recipe's "nfor.KEY", Python's keywords).
    std::vector<std::string> keys;
    /// Takes frames=N in a sequence: the front end reads N neighbouring frames each side
    /// (StageContext::previous_frames) and strips the key before check/make.
    bool cross_frame = false;
    /// Changes the features (albedo, normal, depth, visibility): the chain's output keeps
    /// the input's unless features-out=1.
    bool changes_features = false;
    /// Writes only its colour and extras and reads no extra when probed: may run in SURE's
    /// probed input itself when it is SURE's only denoiser.
    bool probes_in_place = false;
    /// What it reads of variance and half files (mcdn::InputSelection): the halves of the
    /// colour and features (else the variance serves) with these settings, the light
    /// split's components.
    bool (*reads_halves)(const Settings& settings) = with_no_settings;
    bool reads_light_split = false;
    /// Reads the variance (or halves) of other roles than the colour with these settings: of
    /// the features, the light passes, the extras (InputSelection::all_variances).
    bool (*reads_all_variances)(const Settings& settings) = with_any_settings;
    StageFacts facts;
    /// Frame-sized float buffers of the merged input it adds at its peak.
    double frame_buffers = 0;
    /// Bytes it holds besides the frame buffers on `threads` threads (the networks' buffers:
    /// the CNN's per worker thread, OIDN's one window at a time); null: none.
    double (*held_bytes)(const Settings& settings, int threads) = nullptr;
    /// One paragraph for --help, and what it reads (--help STAGE).
    std::string help, needs;
    /// Whether the settings are valid: the Options' parser, no side effects; null: any
    /// key is unknown (a Plan takes none).
    bool (*check)(const Settings& settings, std::string& error) = nullptr;
    /// Makes the stage from valid settings; null for a Plan.
    bool (*make)(MadeStage& made, const Settings& settings, const StageContext& context,
                 std::string& error) = nullptr;
    /// How far a pixel of its result reaches into its input, after the Denoiser `denoiser`
    /// (a mix's network is the one trained for it); null: not at all past its denoisers.
    StageReach (*reach)(const Settings& settings, const std::string& denoiser) = nullptr;
    /// Whether it can run on a resolved AOV set; `how` says how, or what it lacks (--info).
    bool (*can_run)(const AovSet& aovs, std::string& how) = nullptr;
};

/// Every stage, in the order --help lists them: denoise, prefilter, nfor, cnn, oidn, sure,
/// choose, mix.
const std::vector<StageInfo>& stage_table();
/// The entry named `name` or one of its aliases; null when none.
const StageInfo* find_stage(const std::string& name);
/// The names of the entries of the given kinds (all kinds by default), in table order.
std::vector<std::string> stage_names(std::initializer_list<StageKind> kinds = {});

/// What a chain of these stages (each by name, with its own settings) reads of the variance
/// and half-buffer files (read_inputs): the faces of the roles alone; the halves where a
/// stage reads them (StageInfo::reads_halves) or no variance is given (`variance_given`
/// false: the stages take the halves' difference); the light split's faces where a stage
/// splits the colour (reads_light_split); other roles' variances than the colour's where a
/// stage reads them (reads_all_variances); the channels of a stage's `features` setting.
/// With no stage, the roles' faces and the colour's variance; with a name not in the table,
/// everything. Every front end reads through it: mcdntool, the OIIO plugin's recipes,
/// Python's read_inputs(chain=...). The AOV set (InputSelection::aovs) is the caller's.
InputSelection chain_input_selection(const std::vector<std::pair<std::string, Settings>>& stages,
                                     bool variance_given);
/// The same for a chain as run_chain takes it: stage names and the chain's "stage.key"
/// settings (ChainOptions::settings, a recipe's, Python's).
InputSelection chain_input_selection(const std::vector<std::string>& stages,
                                     const Settings& chain_settings, bool variance_given);

}  // namespace mcdn
