// The state one frame's commands work on: the inputs, the AOV spec, and the current image
// (the merged buffer, read lazily at the first command that needs pixels).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/aov.h"
#include "mcdn/chain.h"
#include "mcdn/io.h"
#include "mcdn/settings.h"
#include "mcdn/stages.h"
#include "mcdn/sure.h"

#include "command.h"

namespace mcdntool {

/// One stage of the library in op shape: dst = stage(src).
using StageOp = std::function<bool(OIIO::ImageBuf& dst, const OIIO::ImageBuf& src, int nthreads)>;

class Session {
public:
    int nthreads = 0;
    int frame = -1;                // this frame's number in a sequence, -1 for a single file
    bool verbose = false;          // a line per stage with its time (-v, or stderr is a terminal)
    bool extras_denoised = false;  // a stage of the command line denoises the extra AOVs (-v)
    std::string history;           // the command line, for the written files' Exif:ImageHistory
    /// Which variance and half channels to read (its aovs: the session's aov_spec).
    mcdn::InputSelection selection;

    std::vector<mcdn::InputFile> inputs;
    /// The inputs of the frame `offset` frames away in the shot (the -i commands with the
    /// frame patterns replaced), false when the run is no sequence or a file of that frame
    /// does not exist (before the shot's first frame, after its last).
    std::function<bool(int offset, std::vector<mcdn::InputFile>& inputs)> neighbour_inputs;
    /// Reads the neighbouring frames of a cross-frame stage, up to `radius` on each side,
    /// nearest first, as this frame's inputs are read (and checked); fewer at the shot's
    /// ends (a -v line). False with `error` naming the file.
    bool read_neighbours(int radius, std::vector<std::shared_ptr<OIIO::ImageBuf>>& previous,
                         std::vector<std::shared_ptr<OIIO::ImageBuf>>& next,
                         std::string& error) const;
    mcdn::AovSpec aov_spec;
    /// --fixnan given before the inputs were read: every channel of the frame (and of its
    /// neighbours) is repaired so, before the inputs are checked.
    std::optional<OIIO::ImageBufAlgo::NonFiniteFixMode> input_fix;
    std::string input_fix_name;                // its strategy as given (box3)
    int input_fixed = 0;                       // pixels it repaired in this frame
    std::vector<std::string> output_channels;  // --ch
    std::string last_reference;                // --metrics REF, for --heatmap
    /// A --prefilter changes the features; -o writes the input's own unless a stage asked
    /// for features-out=1.
    bool prefilters = false, features_out = false;
    /// The last --sure's denoiser, which a Mixer after it may run (StageContext::denoiser).
    mcdn::Denoiser estimated_denoiser;

    /// Reads and checks the inputs if not done yet, then runs any queued denoisers:
    /// afterwards image() is the current result.
    bool load(std::string& error);
    /// What load() checks of the inputs from their headers, with `rows` opened on them to
    /// read the merged frame a band at a time (the values are checked as each band is read:
    /// mcdn::validate_inputs); aovs() resolved on its spec.
    bool open_rows(mcdn::InputRows& rows, std::string& error);

    /// Queues a denoiser (--prefilter, --nfor) to run at the next load(); `reach`: how far
    /// it reaches (unknown by default), for SURE's bands.
    void queue(const std::string& name, StageOp op, mcdn::StageReach reach = {})
    {
        m_queue.push_back({ name, std::move(op), reach });
    }
    /// The denoisers run (or queued) since the inputs were read, as one Denoiser for SURE,
    /// with how far they reach (mcdn::chain_radius, -1 unknown), and the image they started
    /// from, moved out of the session: the caller replaces the current image (apply_to); an
    /// error if there is none. Denoisers that already ran (an --info or --metrics came
    /// between) run again inside SURE.
    bool take_denoiser_chain(mcdn::Denoiser& chain, int& chain_radius, OIIO::ImageBuf& chain_input,
                             std::string& error);
    /// Loads, then replaces the current image by op(current image).
    bool apply(const std::string& name, const StageOp& op, std::string& error);
    /// Loads, then replaces the current image by op(input), timing it like apply().
    bool apply_to(const std::string& name, const OIIO::ImageBuf& input, const StageOp& op,
                  std::string& error);
    /// A progress line on a terminal with -v (mcdn/progress.h); empty otherwise.
    mcdn::ProgressCallback progress() const;
    /// Marks the current image stale (a new -i or --aov arrived).
    void invalidate() { m_loaded = false; }
    /// The next stages work on Blender view layer `layer` of the current image (loaded, the
    /// queued stages run first): its AOV set resolved on it, a new chain starting from it
    /// (for --sure), the previous layer's features put back if a prefilter changed them.
    bool switch_layer(const std::string& layer, std::string& error);
    bool loaded() const { return m_loaded; }

    OIIO::ImageBuf& image() { return m_image; }
    const mcdn::AovSet& aovs() const { return m_aovs; }
    /// Replaces the current image by a stage's result and re-resolves the AOV set.
    bool replace_image(OIIO::ImageBuf result, std::string& error);
    /// The input's feature channels back into the current image (before -o), when a
    /// prefilter changed them and no stage asked for features-out.
    bool restore_input_features(std::string& error);

private:
    struct Queued {
        std::string name;
        StageOp op;
        mcdn::StageReach reach;
    };
    bool load_inputs(std::string& error);
    /// What every read frame goes through, this one and each cross-frame neighbour (its AOVs
    /// resolved): --fixnan right after the inputs, then mcdn::InputChecks; -v names the
    /// repaired half-buffer tiles. `fixed`: the pixels --fixnan repaired.
    bool repair_and_check(OIIO::ImageBuf& image, const mcdn::AovSet& aovs, int& fixed,
                          std::string& error) const;
    /// Keeps the feature channels of the chain's input when `stages` hold a prefilter.
    void capture_input_features(const std::vector<Queued>& stages);
    bool m_loaded = false;
    std::vector<Queued> m_queue;    // denoisers waiting for the next load()
    std::vector<Queued> m_applied;  // denoisers that made the current image from m_chain_input
    OIIO::ImageBuf m_chain_input;
    OIIO::ImageBuf m_input_features;  // the feature channels before the first prefilter
    std::vector<std::string> m_feature_names;
    OIIO::ImageBuf m_image;
    mcdn::AovSet m_aovs;
};

/// Prints a -v header line (colour space, preset, features) to stderr unless this run has
/// printed it already: once for a sequence, not per frame or per part; a line that differs
/// (another layer's, a frame detected otherwise) is printed.
void say_once(const std::string& line);

/// Repairs the non-finite values of every channel of `image` by `mode` (--fixnan's
/// strategies, `name` as given); false with the first such value by channel and pixel where
/// the mode is error. `fixed`: the pixels repaired.
bool fix_non_finite(OIIO::ImageBuf& image, OIIO::ImageBufAlgo::NonFiniteFixMode mode,
                    const std::string& name, int nthreads, int& fixed, std::string& error);

/// Built-in command actions (session.cpp).
bool run_input(Session&, const Command&, std::string& error);
bool run_output(Session&, const Command&, std::string& error);
bool run_aov(Session&, const Command&, std::string& error);
bool run_channels(Session&, const Command&, std::string& error);
bool run_info(Session&, const Command&, std::string& error);
bool run_metrics(Session&, const Command&, std::string& error);
bool run_heatmap(Session&, const Command&, std::string& error);
bool run_fixnan(Session&, const Command&, std::string& error);

/// The file an -i command reads: its path, kind and part.
bool input_file_of(const Command& c, mcdn::InputFile& file, std::string& error);
/// Adds an -i command's file to `inputs`: -i:as=seed files one after another are the seeds
/// of one render (mcdn::InputFile::seeds).
void add_input(std::vector<mcdn::InputFile>& inputs, const mcdn::InputFile& file);

/// Checks of the built-in commands' modifier values (session.cpp), run before any command.
bool check_input(const Command&, std::string& error);
bool check_aov(const Command&, std::string& error);
bool check_metrics(const Command&, std::string& error);
bool check_heatmap(const Command&, std::string& error);
bool check_output(const Command&, std::string& error);
bool check_fixnan(const Command&, std::string& error);

/// The -v lines of the safety nets (nfor's, sure's): how many tiles each sent back to the
/// render, from the counts on `result` (none: no line), and choose's share of NFOR, when
/// `stage` is choose or empty (a streamed chain's, mcdn::BandCounts) (session.cpp).
void report_fallback(const OIIO::ImageSpec& result, const std::string& stage = "");
/// The -v line of mcdn::check_halves's repaired tiles (none: no line) (session.cpp).
void report_repaired_halves(int tiles);

/// -o's modifiers as WriteOptions (session.cpp).
bool write_options_of(const Command& c, mcdn::WriteOptions& options, std::string& error);

/// A command line of inputs (-i, --aov), stages and one -o, last, streams: the index of its
/// first stage, else 0 (streamed.cpp).
size_t streamed_chain_start(const std::vector<Command>& commands);
/// A streamed chain's stages and their settings: the commands from `first` to the -o.
void set_chain_stages(mcdn::ChainOptions& chain, const std::vector<Command>& commands,
                      size_t first);
/// Runs such a command line: the inputs, then the stages as one chain in bands, each band's
/// rows written as they are made (mcdn::run_chain's BandSink, mcdn::RowWriter). `streamed`
/// false: only the inputs were run (a multi-part output is written whole); the caller runs
/// the commands from first_stage on.
bool run_streamed_chain(Session& s, const std::vector<Command>& commands, size_t first_stage,
                        bool& streamed, std::string& error);

/// Commands of the library's stages (mcdn/stages.h), with their checks (stages.cpp).
std::vector<CommandInfo> stage_commands();
/// The stage a command runs (--nfor: nfor), null for other commands.
const mcdn::StageInfo* stage_of_command(const std::string& name);
/// `name` is one of them (--denoise, --prefilter, --nfor, --cnn, --sure, --mix).
bool is_stage(const std::string& name);

}  // namespace mcdntool
