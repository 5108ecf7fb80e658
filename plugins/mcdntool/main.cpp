// mcdntool: denoise Monte Carlo renders from the command line, in oiiotool's grammar.
//
//   mcdntool -i beauty.exr -i:as=variance beauty_var.exr -i:as=halfA a.exr -i:as=halfB b.exr
//            --aov:preset=cycles --metrics ref.exr -o out.exr
//
// Commands run left to right on one frame; file names with #, @ or %04d make a sequence
// and the whole command line runs once per frame.
#include <iostream>
#include <atomic>
#include <mutex>
#include <regex>
#include <thread>

#include <unistd.h>

#include <OpenImageIO/argparse.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>
#include <OpenImageIO/sysutil.h>
#include <OpenImageIO/timer.h>

#include "command.h"
#include "session.h"

using namespace mcdntool;
using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil    = OIIO::Strutil;

namespace {

int nargs(const CommandInfo& info) { return int(Strutil::splits(info.metavar, " ").size()); }

// Checks every command word before anything runs, so a typo at the end of a long command
// line fails at once, with a suggestion, instead of after minutes of denoising.
bool check_words(int argc, const char** argv, std::string& error)
{
    for (int i = 1; i < argc; ++i) {
        std::string word = argv[i];
        if (word.size() < 2 || word[0] != '-' || word == "--help" || word == "-h")
            continue;
        Command command = split_command(word);
        if (!check_command(command, error))
            return false;
        const CommandInfo* info = find_command(command.name);
        if (i + nargs(*info) >= argc) {
            error = format("{} needs {} argument(s): {} {}", command.name, nargs(*info),
                           command.name, info->metavar);
            return false;
        }
        i += nargs(*info);
    }
    return true;
}

// A file name with frame numbers in it: '#', '@' or printf's %d.
bool is_sequence(const std::string& name, std::string& normalized, std::string& framespec)
{
    if (!Filesystem::parse_pattern(name.c_str(), 0, normalized, framespec))
        return false;
    static const std::regex printf_frame("%0?[0-9]*d");
    return std::regex_search(normalized, printf_frame);
}

std::string frame_name(const std::string& normalized, int frame)
{
    std::vector<std::string> names;
    Filesystem::enumerate_file_sequence(normalized, { frame }, names);
    return names.empty() ? normalized : names[0];
}

// The frames a command line runs on: --frames, a range written in a pattern
// (shot.1-10#.exr), or every frame of the first input pattern found on disk.
bool find_frames(const std::vector<Command>& commands, const std::string& frames_option,
                 std::vector<int>& frames, std::string& error)
{
    std::string first_input_pattern, pattern_range;
    bool any_sequence = false;
    for (const auto& c : commands)
        for (const auto& arg : c.args) {
            std::string normalized, framespec;
            if (!is_sequence(arg, normalized, framespec))
                continue;
            any_sequence = true;
            if (pattern_range.empty())
                pattern_range = framespec;
            if (c.name == "-i" && first_input_pattern.empty())
                first_input_pattern = normalized;
        }
    if (!any_sequence) {
        if (!frames_option.empty()) {
            error = "--frames given but no file name has a frame pattern (#, @ or %04d)";
            return false;
        }
        return true;
    }
    std::string spec = !frames_option.empty() ? frames_option : pattern_range;
    if (!spec.empty()) {
        if (!Filesystem::enumerate_sequence(spec, frames) || frames.empty()) {
            error = format("--frames {}: not a frame range (e.g. 1-10, 1-100x5, 3,7,9)", spec);
            return false;
        }
        return true;
    }
    std::vector<std::string> files;
    if (first_input_pattern.empty()
        || !Filesystem::scan_for_matching_filenames(first_input_pattern, frames, files)
        || frames.empty()) {
        error = format("no frames found for '{}': give --frames",
                       first_input_pattern.empty() ? "the output pattern" : first_input_pattern);
        return false;
    }
    return true;
}

// Runs the command line on one frame (frame < 0: no sequence).
bool run_frame(const std::vector<Command>& commands, int frame, int nthreads, bool verbose,
               std::string& error)
{
    Session session;
    session.nthreads = nthreads;
    session.verbose = verbose;
    for (Command c : commands) {
        if (frame >= 0)
            for (auto& arg : c.args) {
                std::string normalized, framespec;
                if (is_sequence(arg, normalized, framespec))
                    arg = frame_name(normalized, frame);
            }
        const CommandInfo* info = find_command(c.name);
        if (info->run && !info->run(session, c, error))
            return false;
    }
    // Denoisers queued after the last command that needed pixels still run: their result
    // is what a following -o would have written, and errors must not pass silently.
    return session.load(error);
}

// Runs every frame, `parallel` at a time (each with its share of the threads); a line per
// finished frame. Stops starting frames after the first failure; false if any failed.
bool run_frames(const std::vector<Command>& commands, const std::vector<int>& frames,
                int nthreads, int parallel, bool verbose)
{
    parallel = std::max(1, std::min<int>(parallel, int(frames.size())));
    int threads = nthreads > 0 ? nthreads : int(std::thread::hardware_concurrency());
    int per_frame = std::max(1, threads / parallel);
    std::atomic<size_t> next { 0 }, done { 0 };
    std::atomic<bool> failed { false };
    std::mutex print;
    auto worker = [&] {
        for (size_t f; !failed && (f = next++) < frames.size();) {
            OIIO::Timer timer;
            std::string error;
            bool ok = run_frame(commands, frames[f], parallel > 1 ? per_frame : nthreads,
                                verbose && parallel == 1, error);
            std::lock_guard<std::mutex> lock(print);
            if (!ok) {
                failed = true;
                std::cerr << "mcdntool: error: "
                          << (frames[f] >= 0 ? format("frame {}: ", frames[f]) : std::string())
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
    return !failed;
}

}  // namespace

int main(int argc, const char** argv)
{
    Filesystem::convert_native_arguments(argc, argv);
    std::string error;
    if (!check_words(argc, argv, error)) {
        std::cerr << "mcdntool: error: " << error << "\n";
        return 1;
    }

    std::vector<Command> commands;
    int nthreads = 0;
    bool verbose = isatty(STDERR_FILENO);  // progress lines on a terminal, quiet in pipelines
    std::string frames_option;
    int parallel_frames = 1;
    OIIO::ArgParse ap;
    ap.intro("mcdntool -- denoise Monte Carlo renders (mcdenoise)")
        .usage("mcdntool [-i[:as=KIND] FILE ...] [--aov[:preset=NAME] role=chans ...] "
               "[COMMAND ...] -o FILE")
        .description("Commands run left to right, oiiotool style; every command accepts "
                     ":modifier=value. File names with #, @ or %04d run the whole command "
                     "line once per frame.")
        .epilog("Example:\n  mcdntool -i box.exr -i:as=variance box_var.exr -i:as=halfA "
                "box_A.exr -i:as=halfB box_B.exr --aov:preset=cycles --metrics ref.exr "
                "-o out.exr")
        .exit_on_error(false);
    for (const auto& info : command_table()) {
        std::string decl = info.name + (info.metavar.empty() ? "" : " " + info.metavar);
        std::string help = info.help;
        if (!info.modifiers.empty())
            help += " [modifiers: " + Strutil::join(info.modifiers, ", ") + "]";
        ap.arg(decl.c_str()).help(help).action([&, name = info.name](OIIO::cspan<const char*> a) {
            Command c = split_command(a[0]);
            for (int k = 1; k < int(a.size()); ++k)
                c.args.push_back(a[k]);
            if (name == "--threads")
                nthreads = Strutil::stoi(c.args[0]);
            else if (name == "-v")
                verbose = true;
            else if (name == "--parallel-frames")
                parallel_frames = Strutil::stoi(c.args[0]);
            else if (name == "--frames")
                frames_option = c.args[0];
            else
                commands.push_back(c);
        });
    }
    ap.arg("filename").hidden().action([&](OIIO::cspan<const char*> a) {
        // `role=chans` words belong to the --aov before them; anything else is an input.
        std::string word = a[0];
        if (!commands.empty() && commands.back().name == "--aov"
            && word.find('=') != std::string::npos && !Filesystem::exists(word))
            commands.back().args.push_back(word);
        else
            commands.push_back(Command { "-i", {}, { word } });
    });
    bool help = argc <= 1;
    for (int i = 1; i < argc; ++i)
        help |= std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h";
    if (help) {
        ap.print_help();
        return 0;
    }
    if (ap.parse_args(argc, argv) < 0) {
        std::cerr << "mcdntool: error: " << ap.geterror() << "\n";
        return 1;
    }

    std::vector<int> frames;
    if (!find_frames(commands, frames_option, frames, error)) {
        std::cerr << "mcdntool: error: " << error << "\n";
        return 1;
    }
    if (frames.empty())
        frames.push_back(-1);  // not a sequence: one run
    return run_frames(commands, frames, nthreads, parallel_frames, verbose) ? 0 : 1;
}
