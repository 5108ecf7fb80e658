// Parsing mcdntool's whole command line (command_line.h): OIIO's ArgParse, declared from the
// command table, plus the checks that run before any command.
#include "command_line.h"

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <regex>

#include <OpenImageIO/argparse.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/version.h"

namespace mcdntool {

using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;

namespace {

int nargs(const CommandInfo& info)
{
    return int(Strutil::splits(info.metavar, " ").size());
}

// Checks every command word before ArgParse sees it: ArgParse's own messages have no
// suggestions, and a typo at the end must fail before minutes of denoising.
bool check_words(int argc, const char** argv, std::string& error)
{
    for (int i = 1; i < argc; ++i) {
        std::string word = argv[i];
        if (word.size() < 2 || word[0] != '-' || word == "--help" || word == "-h"
            || word == "--version")
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

// Declares every command of the table to `ap`, filling `line` as ArgParse meets them.
void declare(OIIO::ArgParse& ap, CommandLine& line)
{
    const mcdn::InstallPaths paths = mcdn::install_paths();
    ap.intro(format("mcdntool {} -- denoise Monte Carlo renders (mcdenoise)", mcdn::version()))
        .usage("mcdntool [-i[:as=KIND] FILE ...] [--aov[:preset=NAME] role=chans ...] "
               "[COMMAND ...] -o FILE")
        .description("Commands run left to right, oiiotool style; every command accepts "
                     ":modifier=value, and mcdntool --help COMMAND says what it reads. File "
                     "names with #, @ or %04d run the whole command line once per frame.")
        .epilog(
            format("Examples:\n"
                   "  mcdntool -v -i beauty.exr --denoise -o out.exr\n"
                   "      the best chain the file allows (the renderer is detected: -v says "
                   "which, and why)\n"
                   "  mcdntool -i box.exr -i:as=variance box_var.exr --denoise --metrics ref.exr "
                   "-o out.exr\n"
                   "      a Cycles render with the variance of its mean beside it\n"
                   "  mcdntool -i box.exr -i:as=halfA box_A.exr -i:as=halfB box_B.exr --prefilter "
                   "--nfor -o out.exr\n"
                   "      NFOR on a render with two half buffers\n\n"
                   "Installed data: models {}, colour config {} ($MCDN_MODELS and $OCIO "
                   "override them).\nPlain oiiotool reads .mcdn recipes with this plugin "
                   "folder:\n  export OIIO_LIBRARY_PATH={}",
                   paths.models_dir, paths.ocio_config, paths.plugin_dir))
        .exit_on_error(false);
    for (const auto& info : command_table()) {
        std::string decl = info.name + (info.metavar.empty() ? "" : " " + info.metavar);
        std::string help = info.help;
        if (!info.modifiers.empty())
            help += " [modifiers: " + Strutil::join(info.modifiers, ", ") + "]";
        ap.arg(decl.c_str())
            .help(help)
            .action([&line, name = info.name](OIIO::cspan<const char*> a) {
                Command c = split_command(a[0]);
                for (int k = 1; k < int(a.size()); ++k)
                    c.args.push_back(a[k]);
                if (name == "--threads")
                    line.nthreads = Strutil::stoi(c.args[0]);
                else if (name == "-v")
                    line.verbose = true;
                else if (name == "--parallel-frames")
                    line.parallel_frames = Strutil::stoi(c.args[0]);
                else if (name == "--frames")
                    line.frames = c.args[0];
                else if (name == "--skip-existing")
                    line.skip_existing = true;
                else if (name == "--skip-bad-frames" || name == "--continue")
                    line.skip_bad_frames = true;
                line.commands.push_back(c);
            });
    }
    ap.arg("filename").hidden().action([&line](OIIO::cspan<const char*> a) {
        // `role=chans` words belong to the --aov before them (global commands such as
        // --threads may come between); anything else is an input.
        std::string word = a[0];
        auto& commands = line.commands;
        auto last = std::find_if(commands.rbegin(), commands.rend(),
                                 [](const Command& c) { return !find_command(c.name)->global; });
        if (last != commands.rend() && last->name == "--aov" && word.find('=') != std::string::npos
            && !Filesystem::exists(word))
            last->args.push_back(word);
        else
            commands.push_back(Command { "-i", {}, { word } });
    });
}

}  // namespace

bool wants_version(int argc, const char** argv)
{
    for (int i = 1; i < argc; ++i)
        if (std::string(argv[i]) == "--version")
            return true;
    return false;
}

bool wants_help(int argc, const char** argv, std::string* command)
{
    bool help = argc <= 1;
    for (int i = 1; i < argc; ++i)
        if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
            help = true;
            if (command && i + 1 < argc)
                *command = argv[i + 1];
        }
    return help;
}

bool print_command_help(const std::string& typed)
{
    std::string name = typed;
    if (!find_command(name))
        name = (typed.size() == 1 ? "-" : "--") + typed;  // `--help nfor`, `--help o`
    const CommandInfo* info = find_command(name);
    if (!info) {
        std::vector<std::string> names;
        for (const auto& c : command_table())
            names.push_back(c.name);
        std::string guess = closest("--" + typed, names);
        std::cerr << "mcdntool: no command '" << typed << "'"
                  << (guess.empty() ? std::string() : " (did you mean '" + guess + "'?)")
                  << "; mcdntool --help lists them\n";
        return false;
    }
    auto wrapped = [](const std::string& text) {
        std::string out, line;
        for (const std::string& word : Strutil::splits(text, " ")) {
            if (!line.empty() && line.size() + 1 + word.size() > 76) {
                out += "    " + line + "\n";
                line.clear();
            }
            line += (line.empty() ? "" : " ") + word;
        }
        return out + (line.empty() ? "" : "    " + line + "\n");
    };
    std::cout << info->name << (info->metavar.empty() ? "" : " " + info->metavar) << "\n"
              << wrapped(info->help);
    if (!info->needs.empty())
        std::cout << "\n  Reads:\n" << wrapped(info->needs);
    if (!info->modifiers.empty())
        std::cout << "\n  Modifiers (" << info->name << ":name=value):\n"
                  << wrapped(Strutil::join(info->modifiers, ", "));
    return true;
}

void print_help()
{
    OIIO::ArgParse ap;
    CommandLine unused;
    declare(ap, unused);
    ap.print_help();
}

bool parse_command_line(int argc, const char** argv, CommandLine& line, std::string& error)
{
    if (!check_words(argc, argv, error))
        return false;
    std::vector<std::string> words { "mcdntool" };
    for (int i = 1; i < argc; ++i)
        words.push_back(argv[i]);
    line.text = Strutil::join(words, " ");
    OIIO::ArgParse ap;
    declare(ap, line);
    if (ap.parse_args(argc, argv) < 0) {
        error = ap.geterror();
        return false;
    }
    for (const auto& command : line.commands) {
        const CommandInfo* info = find_command(command.name);
        if (info->check && !info->check(command, error))
            return false;
    }
    return true;
}

bool is_sequence(const std::string& name, std::string& normalized, std::string& framespec)
{
    if (!Filesystem::parse_pattern(name.c_str(), 0, normalized, framespec))
        return false;
    // parse_pattern leaves the rest of the name as it is, and frame_name's printf would
    // read a second '%' (shot%s.#.exr, 100%.#.exr) as a conversion with no argument.
    if (std::count(normalized.begin(), normalized.end(), '%') != 1)
        return false;
    // A frame number has at most 10 digits; a wider field (%088888888884d) would abort
    // OIIO's formatting: such a name is taken literally.
    static const std::regex printf_frame("%0?([0-9]*)d");
    std::smatch match;
    if (!std::regex_search(normalized, match, printf_frame))
        return false;
    const std::string width = match[1].str();
    return width.size() <= 2 && (width.empty() || std::stoi(width) <= 10);
}

int frame_patterns(const std::string& name)
{
    // Runs of # or @ (oiiotool's padding characters) and printf conversions %d, %04d.
    static const std::regex pattern("[#@]+|%0?[0-9]*d");
    return int(std::distance(std::sregex_iterator(name.begin(), name.end(), pattern),
                             std::sregex_iterator()));
}

std::string frame_name(const std::string& normalized, int frame)
{
    std::vector<std::string> names;
    Filesystem::enumerate_file_sequence(normalized, { frame }, names);
    return names.empty() ? normalized : names[0];
}

bool frames_from_spec(const std::string& spec, std::vector<int>& frames, std::string& error,
                      size_t max_frames)
{
    // Filesystem::enumerate_sequence walks every number between a range's ends (whatever
    // the step) and collects them all: bound the walk first, with the same parser it uses.
    int64_t walk = 0;
    bool ok = !spec.empty();
    for (OIIO::string_view range : Strutil::splitsv(spec, ",")) {
        int first = 1, last = 1;
        ok &= Strutil::parse_int(range, first);
        last = first;
        if (Strutil::parse_char(range, '-'))
            ok &= Strutil::parse_int(range, last);
        walk += std::llabs(int64_t(last) - int64_t(first)) + 1;
    }
    if (ok && walk > int64_t(max_frames)) {
        error = format("--frames {}: more than {} frames", spec, max_frames);
        return false;
    }
    if (!ok || !Filesystem::enumerate_sequence(spec, frames) || frames.empty()) {
        error = format("--frames {}: not a frame range (e.g. 1-10, 1-100x5, 3,7,9)", spec);
        return false;
    }
    return true;
}

bool check_frames(const Command& command, std::string& error)
{
    std::vector<int> frames;
    return frames_from_spec(command.args[0], frames, error);
}

}  // namespace mcdntool
