// The command table and the parsing of `--name:modifier=value` words.
#include "command.h"

#include <algorithm>

#include <OpenImageIO/strutil.h>

#include "mcdn/settings.h"
#include "mcdn/threads.h"

#include "command_line.h"
#include "session.h"

namespace mcdntool {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

std::string Command::modifier(const std::string& key, const std::string& fallback) const
{
    auto it = modifiers.find(key);
    return it == modifiers.end() ? fallback : it->second;
}

bool Command::number(const std::string& key, double& value, std::string& error) const
{
    if (has(key) && !mcdn::parse_finite(modifier(key), value)) {
        error = format("{}:{}={} is not a number", name, key, modifier(key));
        return false;
    }
    return true;
}

namespace {

// The N of --threads (0 = all cores) and --parallel-frames (at least 1).
CommandCheck whole_number_at_least(int minimum)
{
    return [minimum](const Command& c, std::string& error) {
        if (Strutil::string_is_int(c.args[0]) && Strutil::stoi(c.args[0]) >= minimum)
            return true;
        error = format("{} {}: needs a whole number >= {}", c.name, c.args[0], minimum);
        return false;
    };
}

// --threads N: the library's rule (mcdn/threads.h), as the plugin and Python apply it.
bool check_thread_count(const Command& c, std::string& error)
{
    int n = 0;
    if (mcdn::parse_threads(c.args[0], n, error))
        return true;
    error = "--threads " + c.args[0] + ": " + error;
    return false;
}

}  // namespace

namespace {

// The commands on the image of a frame: its inputs, what it is, its output.
std::vector<CommandInfo> image_commands()
{
    return {
        { "-i",
          "FILE",
          { "as", "part" },
          "Add an input: the render (as=mean, the default), the per-pixel variance of its "
          "mean (as=variance), or a half buffer (as=halfA, as=halfB). as=seed: one of "
          "K renders of the frame that differ only in their seed (Cycles' Seed, Arnold's "
          "AA_seed), given one after another: read as one render, their mean, with the "
          "variance of the mean and, for an even K, two halves (what Blender does not "
          "write; --nfor, --sure, --mix and frames=N need them). A directory is read "
          "as a Tungsten buffer set (color.pfm, colorA.pfm, colorVariance.pfm, ...). "
          "A multi-part EXR is read as one set of channels (the first part's as they "
          "are, the others' behind their part's name) and written back with the same "
          "parts; part=NAME[,NAME...] reads those parts alone. Parts of other data windows (a "
          "stereo file's views) are denoised each in turn, as view layers are. A bare FILE "
          "is the same as -i FILE.",
          run_input,
          false,
          check_input,
          {} },
        { "--aov",
          "",
          { "preset", "layer", "colorspace" },
          "Say which channels are what: preset=cycles|arnold|renderman|tungsten|oidn|"
          "generic (default: detected from the channel names, printed with -v), "
          "colorspace=NAME (OCIO space of the colour channels; default the file's "
          "oiio:ColorSpace, else scene_linear); "
          "role=ch1,ch2,ch3 words after it override one role (color, color_variance, "
          "color_a, albedo, normal, depth, ..., extra.NAME=...).",
          run_aov,
          false,
          check_aov,
          {} },
        { "--info",
          "",
          { "verbose" },
          "Print the image size, channels and the resolved AOV roles.",
          run_info,
          false,
          {},
          {} },
        { "--metrics",
          "REF",
          { "format", "trim", "channels" },
          "Print MSE, RMSE, relMSE, SMAPE, PSNR and SSIM of the colour against a reference "
          "image (format=text|json, trim=1 drops the 0.01% best and worst pixels, "
          "channels=a,b,c compares other channels).",
          run_metrics,
          false,
          check_metrics,
          {} },
        { "--heatmap",
          "FILE",
          { "ref", "metric", "min", "max" },
          "Write a false-colour per-pixel error PNG against the last --metrics reference "
          "(or ref=FILE): metric=relmse|se|ae|smape, log10 range min=-4 max=0.",
          run_heatmap,
          false,
          check_heatmap,
          {} },
        { "--ch",
          "CHANNELS",
          {},
          "Channels -o writes, comma-separated, each a name or a wildcard (mix.alpha.*, "
          "*.R); default: the render's own channels and those a stage was asked to add "
          "(nfor's mse=1 and selection=1, mix's alpha=1).",
          run_channels,
          false,
          {},
          {} },
        { "-o",
          "FILE",
          { "datatype", "compression" },
          "Write the current image. Each channel keeps the pixel type it had in the "
          "input and the file its compression, as oiiotool keeps them (channels the "
          "stages add are float); datatype=half|float gives every channel one type, "
          "compression=zip, piz, dwaa:45, ... another compression. "
          "Written to a temporary name and renamed: never a partial file.",
          run_output,
          false,
          check_output,
          {} },
        { "--fixnan",
          "STRATEGY",
          {},
          "Repair NaN and Inf in every channel, as oiiotool does: none, black (0), "
          "box3 (the 3x3 neighbours' mean) or error (fail if there are any). Right "
          "after the inputs (-i F --fixnan box3 --denoise) it repairs them as they are "
          "read, before they are checked (a cross-frame stage's neighbours too); later, "
          "the current image. No stage makes them.",
          run_fixnan,
          false,
          check_fixnan,
          {} },
    };
}

// The commands on the whole run: threads, messages, the frames of a sequence.
std::vector<CommandInfo> run_options()
{
    return {
        { "--threads",
          "N",
          {},
          "Worker threads (0 = all cores, the default).",
          nullptr,
          true,
          check_thread_count,
          {} },
        { "-v",
          "",
          {},
          "Print a line per stage with its run time (the default when "
          "stderr is a terminal).",
          nullptr,
          true,
          {},
          {} },
        { "--frames",
          "SPEC",
          {},
          "Frames for # / @ / %04d patterns, e.g. 1-10 or 1-100x5 (default: every frame "
          "of the first input pattern that exists on disk).",
          nullptr,
          true,
          check_frames,
          {} },
        { "--parallel-frames",
          "N",
          {},
          "Denoise N frames of a sequence at once, sharing the threads (default 1).",
          nullptr,
          true,
          whole_number_at_least(1),
          {} },
        { "--skip-existing",
          "",
          {},
          "Frames whose every output (-o, --heatmap) exists already are skipped, with a "
          "line each: a farm job that died half-way is run again as it was.",
          nullptr,
          true,
          {},
          {} },
        { "--skip-bad-frames",
          "",
          {},
          "A frame that fails does not stop the sequence: the others are denoised, the "
          "failed ones listed at the end, and the exit status is 1 (as oiiotool's "
          "--skip-bad-frames; alias --continue).",
          nullptr,
          true,
          {},
          {} },
        { "--continue", "", {}, "Alias of --skip-bad-frames.", nullptr, true, {}, {} },
    };
}

}  // namespace

const std::vector<CommandInfo>& command_table()
{
    static const std::vector<CommandInfo> table = [] {
        std::vector<CommandInfo> t = image_commands();
        for (auto& command : run_options())
            t.push_back(command);
        for (auto& stage : stage_commands())
            t.push_back(stage);
        return t;
    }();
    return table;
}

const CommandInfo* find_command(const std::string& name)
{
    for (const auto& c : command_table())
        if (c.name == name)
            return &c;
    return nullptr;
}

Command split_command(const std::string& typed)
{
    Command command;
    auto parts = OIIO::Strutil::splits(typed, ":");
    command.name = parts.empty() ? typed : parts[0];
    std::string last;  // the modifier that took the last value
    for (size_t i = 1; i < parts.size(); ++i) {
        size_t eq = parts[i].find('=');
        // A number after a value continues it, as in oiiotool's compression=zip:5 and
        // compression=dwaa:45: a level, not a modifier of its own.
        if (eq == std::string::npos && !last.empty() && OIIO::Strutil::string_is_int(parts[i]))
            command.modifiers[last] += ":" + parts[i];
        else if (eq == std::string::npos) {
            command.modifiers[parts[i]] = "1";
            last.clear();
        } else {
            last = parts[i].substr(0, eq);
            command.modifiers[last] = parts[i].substr(eq + 1);
        }
    }
    return command;
}

std::string closest(const std::string& word, const std::vector<std::string>& candidates)
{
    auto distance = [](const std::string& a, const std::string& b) {
        std::vector<size_t> row(b.size() + 1);
        for (size_t j = 0; j <= b.size(); ++j)
            row[j] = j;
        for (size_t i = 1; i <= a.size(); ++i) {
            size_t diagonal = row[0];
            row[0] = i;
            for (size_t j = 1; j <= b.size(); ++j) {
                size_t up = row[j];
                row[j] = std::min(
                    { row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1) });
                diagonal = up;
            }
        }
        return row[b.size()];
    };
    std::string best;
    size_t best_distance = std::max<size_t>(3, word.size() / 2) + 1;
    for (const auto& c : candidates) {
        size_t d = distance(word, c);
        if (d < best_distance) {
            best_distance = d;
            best = c;
        }
    }
    return best;
}

bool check_command(const Command& command, std::string& error)
{
    const CommandInfo* info = find_command(command.name);
    if (!info) {
        std::vector<std::string> names;
        for (const auto& c : command_table())
            names.push_back(c.name);
        std::string guess = closest(command.name, names);
        error = format("unknown command '{}'{}; see mcdntool --help", command.name,
                       guess.empty() ? std::string() : format(" (did you mean '{}'?)", guess));
        return false;
    }
    for (const auto& [key, value] : command.modifiers) {
        if (std::find(info->modifiers.begin(), info->modifiers.end(), key) != info->modifiers.end())
            continue;
        std::string guess = closest(key, info->modifiers);
        error = format("{}: unknown modifier ':{}'{} (it takes: {})", command.name, key,
                       guess.empty() ? std::string() : format(" (did you mean ':{}'?)", guess),
                       info->modifiers.empty() ? std::string("none")
                                               : OIIO::Strutil::join(info->modifiers, ", "));
        return false;
    }
    return true;
}

}  // namespace mcdntool
