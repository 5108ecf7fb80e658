// mcdntool: denoise Monte Carlo renders from the command line, in oiiotool's grammar.
//
//   mcdntool -i beauty.exr -i:as=variance beauty_var.exr -i:as=halfA a.exr -i:as=halfB b.exr
//            --aov:preset=cycles --metrics ref.exr -o out.exr
//
// Commands run left to right on one frame; file names with #, @ or %04d make a sequence
// and the whole command line runs once per frame.
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <new>
#include <atomic>
#include <mutex>
#include <thread>

#include <signal.h>
#include <unistd.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>
#include <OpenImageIO/sysutil.h>
#include <OpenImageIO/timer.h>

#include "mcdn/threads.h"
#include "mcdn/version.h"

#include "command_line.h"
#include "frames.h"
#include "memory.h"
#include "session.h"

using namespace mcdntool;
using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;

namespace {

// Whether a stage of the command line denoises the extra AOVs (a denoiser or plan with the
// `extras` key, not set to 0), for -v.
bool denoises_extras(const std::vector<Command>& commands)
{
    for (const auto& c : commands) {
        const mcdn::StageInfo* stage = stage_of_command(c.name);
        if (stage
            && std::find(stage->keys.begin(), stage->keys.end(), "extras") != stage->keys.end()
            && c.modifier("extras") != "0")
            return true;
    }
    return false;
}

// What the command line's stages read of the variance and half-buffer files: the faces of
// the roles, and the halves only where NFOR or its prefilter runs (StageInfo::reads_halves:
// --denoise and --choose run it beside the CNN; or where no variance is given, from which the
// stages then take the halves' difference), the light split's only for the CNN, and only
// the colour's where every stage reads no other (StageInfo::reads_all_variances: --oidn,
// --sure, --mix, --denoise:choose=0 with OIDN's weights).
// Everything when a command names channels. --info without a stage reads what any stage
// could, so that it says what each can do with the files given.
mcdn::InputSelection input_selection(const std::vector<Command>& commands)
{
    std::vector<std::pair<std::string, mcdn::Settings>> stages;
    bool variance = false, info = false, stage = false, every_channel = false;
    for (const auto& c : commands) {
        info |= c.name == "--info";
        stage |= is_stage(c.name);
        every_channel |= c.name == "--ch" || (c.name == "--info" && c.has("verbose"))
                         || (c.name == "--metrics" && c.has("channels"));
        if (const mcdn::StageInfo* reads = stage_of_command(c.name))
            stages.emplace_back(reads->name, c.modifiers);
        variance |=
            c.name == "-i" && (c.modifier("as") == "variance" || c.modifier("as") == "seed");
    }
    mcdn::InputSelection selection = mcdn::chain_input_selection(stages, variance);
    selection.only_roles &= !every_channel;
    selection.light_split |= info;
    selection.halves |= info && !stage;
    selection.all_variances |= info || !stage;
    return selection;
}

// The commands [begin, end) in order.
bool run_commands(Session& session, const std::vector<Command>& commands, size_t begin, size_t end,
                  std::string& error)
{
    for (size_t i = begin; i < end; ++i) {
        const CommandInfo* info = find_command(commands[i].name);
        if (info->run && !info->run(session, commands[i], error))
            return false;
    }
    return true;
}

// The render's first input file (-i as the mean or a seed): what its layers and parts are
// read from; empty when there is none.
std::string first_render_input(const std::vector<Command>& commands)
{
    for (const auto& c : commands)
        if (c.name == "-i" && (c.modifier("as", "mean") == "mean" || c.modifier("as") == "seed"))
            return c.args[0];
    return {};
}

// The Blender view layers to denoise in turn: every layer of the first render input when it
// has several and no --aov picks a layer, names channels or another preset.
std::vector<std::string> layers_to_denoise(const std::vector<Command>& commands)
{
    for (const auto& c : commands)
        if (c.name == "--aov"
            && (c.has("layer") || !c.args.empty()
                || (c.has("preset") && c.modifier("preset") != "cycles"
                    && c.modifier("preset") != "auto")))
            return {};
    const std::string first_input = first_render_input(commands);
    auto in = first_input.empty() ? nullptr : OIIO::ImageInput::open(first_input);
    if (!in) {
        OIIO::geterror();  // reading says what is wrong, naming the file
        return {};
    }
    std::vector<std::string> layers = mcdn::blender_view_layers(in->spec());
    return layers.size() > 1 ? layers : std::vector<std::string>();
}

// The parts of one data window of a multi-part EXR, in the file's order: a stereo file's
// view (OpenEXR's multi-part multi-view files give each view its own window).
struct WindowParts {
    std::string label;  // the first part's view attribute, else its name
    std::vector<std::string> names;
};

// The first render input's parts grouped by data window, when there are several windows
// and no -i picks parts itself; else empty (one merged set of channels).
std::vector<WindowParts> parts_by_window(const std::vector<Command>& commands)
{
    for (const auto& c : commands)
        if (c.name == "-i" && (c.has("part") || c.modifier("as") == "seed"))
            return {};
    const std::string first = first_render_input(commands);
    auto in = first.empty() ? nullptr : OIIO::ImageInput::open(first);
    if (!in) {
        OIIO::geterror();  // reading says what is wrong, naming the file
        return {};
    }
    std::vector<WindowParts> groups;
    std::vector<OIIO::ROI> windows;
    for (int s = 0; in->seek_subimage(s, 0); ++s) {
        const OIIO::ImageSpec& spec = in->spec();
        const OIIO::ROI window(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height);
        const std::string name = spec.get_string_attribute("name");
        if (name.empty())
            return {};  // parts without names cannot be picked: the reader says what is wrong
        auto at = std::find(windows.begin(), windows.end(), window);
        if (at == windows.end()) {
            windows.push_back(window);
            groups.push_back({ spec.get_string_attribute("view", name), {} });
            at = windows.end() - 1;
        }
        groups[size_t(at - windows.begin())].names.push_back(name);
    }
    return groups.size() > 1 ? groups : std::vector<WindowParts>();
}

// Runs the command line of one frame, one of `parallel` frames that run at once on
// `all_threads` threads together (memory is checked for all of them).
bool run_frame(const std::vector<Command>& commands, const std::string& history, int nthreads,
               int all_threads, int parallel, bool verbose, std::string& error, int frame,
               std::function<bool(int, std::vector<mcdn::InputFile>&)> neighbour_inputs);

// Each data window's parts through the whole command line in turn, written to a temporary
// beside the output; then the output made of every part in the file's order, each with its
// own window, and the temporaries removed (also on failure).
bool run_views(const std::vector<Command>& commands, const std::vector<WindowParts>& views,
               const std::string& history, int nthreads, int all_threads, int parallel,
               bool verbose, std::string& error, int frame,
               const std::function<bool(int, std::vector<mcdn::InputFile>&)>& neighbour_inputs)
{
    std::vector<std::string> labels;
    for (const WindowParts& v : views)
        labels.push_back(v.label);
    size_t outputs = 0, output = 0;
    for (size_t i = 0; i < commands.size(); ++i)
        if (commands[i].name == "-o")
            ++outputs, output = i;
    const std::string input = first_render_input(commands);
    if (outputs != 1 || !Strutil::iends_with(commands[output].args[0], ".exr")) {
        error = format("{}: its parts differ in data window (views {}), and each is denoised in "
                       "turn into one EXR: give one -o FILE.exr (or -i:part=NAME for one)",
                       input, Strutil::join(labels, ", "));
        return false;
    }
    const std::string path = commands[output].args[0];
    const std::string dir =
        Filesystem::parent_path(path).empty() ? std::string(".") : Filesystem::parent_path(path);
    // Named as mcdn's temporaries (mcdn/io.h write_image): a killed run's are found.
    const std::string stem =
        format("{}/.{}.mcdn-tmp-{}-view", dir, Filesystem::filename(path), getpid());
    std::vector<std::string> temporaries;
    struct Remove {
        std::vector<std::string>& paths;
        ~Remove()
        {
            for (const std::string& p : paths)
                Filesystem::remove(p);
        }
    } remove { temporaries };
    if (verbose)
        std::cerr << format("mcdntool: {}: parts of {} data windows (views {}): each denoised "
                            "in turn (-i:part=NAME for one)\n",
                            input, views.size(), Strutil::join(labels, ", "));
    for (size_t k = 0; k < views.size(); ++k) {
        const std::string parts = Strutil::join(views[k].names, ",");
        std::vector<Command> view = commands;
        for (Command& c : view)
            if (c.name == "-i")
                c.modifiers["part"] = parts;
        temporaries.push_back(format("{}{}.exr", stem, k));
        view[output].args[0] = temporaries.back();
        if (verbose)
            std::cerr << format("mcdntool: view '{}' ({} of {}): parts {}\n", views[k].label, k + 1,
                                views.size(), parts);
        auto inputs = [&neighbour_inputs, parts](int offset, std::vector<mcdn::InputFile>& in) {
            if (!neighbour_inputs || !neighbour_inputs(offset, in))
                return false;
            for (mcdn::InputFile& f : in)
                f.part = parts;
            return true;
        };
        if (!run_frame(view, history, nthreads, all_threads, parallel, verbose, error, frame,
                       inputs))
            return false;
    }
    // Every part in the file's order, from the temporary of its window.
    std::vector<OIIO::ImageSpec> specs;
    std::vector<std::vector<unsigned char>> pixels;
    auto original = OIIO::ImageInput::open(input);
    for (int s = 0; original && original->seek_subimage(s, 0); ++s) {
        const OIIO::ImageSpec part = original->spec();
        const std::string name = part.get_string_attribute("name");
        size_t k = 0;
        while (k < views.size()
               && std::find(views[k].names.begin(), views[k].names.end(), name)
                      == views[k].names.end())
            ++k;
        auto in = k < views.size() ? OIIO::ImageInput::open(temporaries[k]) : nullptr;
        bool found = false;
        for (int t = 0; in && !found && in->seek_subimage(t, 0); ++t) {
            if (in->spec().get_string_attribute("name") != name)
                continue;
            specs.push_back(in->spec());
            if (part.extra_attribs.contains("view"))
                specs.back().attribute("view", part.get_string_attribute("view"));
            pixels.emplace_back(specs.back().image_bytes(true));
            found = in->read_image(t, 0, 0, specs.back().nchannels, OIIO::TypeUnknown,
                                   pixels.back().data());
        }
        if (!found) {
            error = format("{}: part '{}' was not written: {}", path, name,
                           in ? in->geterror() : OIIO::geterror());
            return false;
        }
    }
    const std::string assembled = stem + "s.exr";
    temporaries.push_back(assembled);
    auto out = OIIO::ImageOutput::create(assembled);
    bool ok = out && out->open(assembled, int(specs.size()), specs.data());
    for (size_t p = 0; ok && p < specs.size(); ++p)
        ok = (p == 0 || out->open(assembled, specs[p], OIIO::ImageOutput::AppendSubimage))
             && out->write_image(OIIO::TypeUnknown, pixels[p].data());
    ok = ok && out->close();
    if (!ok) {
        error = format("{}: {}", path, out ? out->geterror() : OIIO::geterror());
        return false;
    }
    if (!Filesystem::rename(assembled, path, error)) {
        error = format("{}: {}", path, error);
        return false;
    }
    temporaries.pop_back();
    return true;
}

bool run_frame(const std::vector<Command>& commands, const std::string& history, int nthreads,
               int all_threads, int parallel, bool verbose, std::string& error, int frame = -1,
               std::function<bool(int, std::vector<mcdn::InputFile>&)> neighbour_inputs = {})
{
    if (!check_inputs(commands, error) || !check_outputs(commands, error))
        return false;
    // A file of several data windows (a stereo file's views): each window's parts in turn.
    if (const std::vector<WindowParts> views = parts_by_window(commands); !views.empty())
        return run_views(commands, views, history, nthreads, all_threads, parallel, verbose, error,
                         frame, neighbour_inputs);
    if (!check_memory(commands, all_threads, parallel, error))
        return false;
    Session session;
    session.neighbour_inputs = std::move(neighbour_inputs);
    session.frame = frame;
    session.nthreads = nthreads;
    session.verbose = verbose;
    session.history = history;
    session.selection = input_selection(commands);
    session.extras_denoised = denoises_extras(commands);
    size_t next = 0;  // the first command not yet run
    // A file of several Blender view layers: the stages up to the first -o run once per
    // layer, each on its own AOV set (the other layers' channels pass through).
    const std::vector<std::string> layers = layers_to_denoise(commands);
    if (!layers.empty()) {
        session.selection.layers = layers;
        size_t first_stage = 0, end = commands.size();
        while (first_stage < commands.size() && !is_stage(commands[first_stage].name))
            ++first_stage;
        for (size_t i = first_stage; i < commands.size(); ++i)
            if (commands[i].name == "-o") {
                end = i;
                break;
            }
        if (first_stage < end) {
            if (verbose)
                std::cerr << format("mcdntool: view layers {}: each denoised in turn "
                                    "(--aov:layer=NAME for one)\n",
                                    Strutil::join(layers, ", "));
            if (!run_commands(session, commands, 0, first_stage, error))
                return false;
            for (size_t k = 0; k < layers.size(); ++k) {
                if (verbose)
                    std::cerr << format("mcdntool: view layer '{}' ({} of {})\n", layers[k], k + 1,
                                        layers.size());
                if (!session.switch_layer(layers[k], error)
                    || !run_commands(session, commands, first_stage, end, error))
                    return false;
            }
            next = end;
        }
    } else if (const size_t first_stage = streamed_chain_start(commands)) {
        bool streamed = false;
        if (!run_streamed_chain(session, commands, first_stage, streamed, error))
            return false;
        if (streamed)
            return true;
        next = first_stage;
    } else if (verbose && std::any_of(commands.begin(), commands.end(), [](const Command& c) {
                   return is_stage(c.name);
               })) {
        std::cerr << "mcdntool: the stages run command by command, the frame whole in memory "
                     "(a command line of -i and --aov, stages, one -o last streams in bands "
                     "of rows)\n";
    }
    if (!run_commands(session, commands, next, commands.size(), error))
        return false;
    // Denoisers queued after the last command that needed pixels still run: their result
    // is what a following -o would have written, and errors must not pass silently.
    return session.load(error);
}

// Runs every frame, `parallel` at a time (each with its share of the threads); a line per
// finished frame. Stops starting frames after the first failure unless --skip-bad-frames
// (then the failed frames are listed at the end); false if any failed.
bool run_frames(const std::vector<Command>& commands, const std::vector<int>& frames,
                const CommandLine& line)
{
    const int nthreads = line.nthreads;
    int parallel = line.parallel_frames;
    const bool verbose = line.verbose;
    std::vector<int> bad;
    parallel = std::max(1, std::min<int>(parallel, int(frames.size())));
    int threads = nthreads > 0 ? nthreads : int(std::thread::hardware_concurrency());
    int per_frame = std::max(1, threads / parallel);
    std::atomic<size_t> next { 0 }, done { 0 };
    std::atomic<bool> failed { false };
    std::mutex print;
    mcdn::start_threads(threads);
    auto worker = [&] {
        for (size_t f; (!failed || line.skip_bad_frames) && (f = next++) < frames.size();) {
            OIIO::Timer timer;
            std::string error;
            bool ok = false;
            const std::vector<Command> frame = frame_commands(commands, frames[f]);
            if (line.skip_existing && outputs_exist(frame)) {
                std::lock_guard<std::mutex> lock(print);
                std::cerr << format("mcdntool: frame {} ({}/{}) skipped: its outputs exist "
                                    "(--skip-existing)\n",
                                    frames[f], ++done, frames.size());
                continue;
            }
            try {
                const int number = frames[f];
                ok = run_frame(frame, line.text, parallel > 1 ? per_frame : nthreads, threads,
                               parallel, verbose && parallel == 1, error, number,
                               [&commands, number](int offset, std::vector<mcdn::InputFile>& in) {
                                   return shot_frame_inputs(commands, number + offset, in);
                               });
            } catch (const std::bad_alloc&) {
                // A frame too large for the memory left: one line and a non-zero exit, not
                // an abort (outputs go through a temporary name: nothing partial is left).
                error = "out of memory for this frame (fewer input channels, or a smaller "
                        "--cnn:tile, need less)";
            } catch (const std::exception& e) {
                // What a library throws where it cannot go on (a thread it could not create
                // when memory ran out, TBB's "pthread_create has failed"): the frame fails.
                error = format("{} (out of memory or threads?)", e.what());
            }
            std::lock_guard<std::mutex> lock(print);
            if (!ok) {
                // Counted as done too: the next frame's count goes on from this one's.
                failed = true;
                bad.push_back(frames[f]);
                ++done;
                std::cerr << "mcdntool: error: "
                          << (frames[f] >= 0 && frames.size() > 1 ? format(
                                  "frame {} ({}/{}): ", frames[f], done.load(), frames.size())
                              : frames[f] >= 0 ? format("frame {}: ", frames[f])
                                               : std::string())
                          << error << "\n";
            } else if (frames[f] >= 0)
                std::cerr << format("mcdntool: frame {} ({}/{}) done in {:.2f} s\n", frames[f],
                                    ++done, frames.size(), timer());
        }
    };
    std::vector<std::thread> pool;
    for (int i = 1; i < parallel; ++i)
        pool.emplace_back(worker);
    worker();
    for (auto& t : pool)
        t.join();
    if (line.skip_bad_frames && !bad.empty() && frames.size() > 1) {
        std::sort(bad.begin(), bad.end());
        std::vector<std::string> names;
        for (int f : bad)
            names.push_back(std::to_string(f));
        std::cerr << format("mcdntool: {} of {} frames failed: {}\n", bad.size(), frames.size(),
                            Strutil::join(names, ","));
    }
    return !failed;
}

// A command line that denoises but neither writes nor measures the result does all the work
// for nothing: said.
void warn_without_output(const std::vector<Command>& commands)
{
    bool denoises = false, uses = false;
    for (const auto& c : commands) {
        denoises |= is_stage(c.name);
        uses |= c.name == "-o" || c.name == "--metrics" || c.name == "--heatmap";
    }
    if (denoises && !uses)
        std::cerr << "mcdntool: warning: no -o: the denoised image is not written\n";
}

// SIGINT, SIGTERM, SIGHUP: the output being written is removed, then the signal takes its
// default course (the shell sees 130, 143, 129). Only async-signal-safe calls.
extern "C" void remove_outputs_and_die(int sig)
{
    mcdn::remove_temporary_outputs();
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

void install_signal_handlers()
{
    for (int sig : { SIGINT, SIGTERM, SIGHUP }) {
        struct sigaction action { };
        action.sa_handler = remove_outputs_and_die;
        sigemptyset(&action.sa_mask);
        ::sigaction(sig, &action, nullptr);
    }
}

}  // namespace

int main(int argc, const char** argv)
{
    install_signal_handlers();
    keep_freed_memory();
    // Debian's OIIO prints its debug channel ("OIIO DEBUG: ImageBuf unable to allocate ...")
    // by default: what it says, an error line says; $OPENIMAGEIO_DEBUG still turns it on.
    if (!std::getenv("OPENIMAGEIO_DEBUG"))
        OIIO::attribute("debug", 0);
    Filesystem::convert_native_arguments(argc, argv);
    if (wants_version(argc, argv)) {
        std::cout << "mcdntool " << mcdn::version() << "\n";
        return 0;
    }
    std::string help_command;
    if (wants_help(argc, argv, &help_command)) {
        if (!help_command.empty())
            return print_command_help(help_command) ? 0 : 1;
        print_help();
        return 0;
    }
    CommandLine line;
    line.verbose = isatty(STDERR_FILENO);  // progress lines on a terminal, quiet in pipelines
    std::vector<int> frames;
    std::string error;
    if (!parse_command_line(argc, argv, line, error)
        || !find_frames(line.commands, line.frames, frames, error)) {
        std::cerr << "mcdntool: error: " << error << "\n";
        return 1;
    }
    if (frames.empty())
        frames.push_back(-1);  // not a sequence: one run
    warn_without_output(line.commands);
    return run_frames(line.commands, frames, line) ? 0 : 1;
}
