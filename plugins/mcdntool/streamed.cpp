// A command line that reads, runs stages and writes one file streams: the stages run as one
// chain in bands of rows (mcdn/chain.h), each band's rows written as soon as they are made
// (mcdn::RowWriter), so that besides the input only one band is in memory. Any other
// command line runs command by command (session.cpp).
#include <iostream>

#include <OpenImageIO/strutil.h>
#include <OpenImageIO/timer.h>

#include "mcdn/chain.h"
#include "mcdn/denoise.h"
#include "mcdn/skip.h"

#include "session.h"

namespace mcdntool {

using OIIO::ImageBuf;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

// --threads, -v, --frames, ...: set once for the run wherever they stand (oiiotool's -v
// likewise), so they neither end a streamed chain nor are a stage of it.
bool is_global(const Command& c)
{
    const CommandInfo* info = find_command(c.name);
    return info && info->global;
}

}  // namespace

void set_chain_stages(mcdn::ChainOptions& chain, const std::vector<Command>& commands, size_t first)
{
    chain.stages.clear();
    for (size_t i = first; i + 1 < commands.size(); ++i) {
        if (is_global(commands[i]))
            continue;
        const std::string stage = commands[i].name.substr(2);
        chain.stages.push_back(stage);
        for (const auto& [key, value] : commands[i].modifiers)
            chain.settings[stage + "." + key] = value;
    }
}

size_t streamed_chain_start(const std::vector<Command>& commands)
{
    // -i and --aov commands, then stages only, then one -o, last; the commands set once
    // for the run (is_global) anywhere.
    auto setup = [](const Command& c) {
        return c.name == "-i" || c.name == "--aov" || is_global(c);
    };
    size_t first = 0;
    while (first < commands.size() && setup(commands[first]))
        ++first;
    if (first == commands.size() || !is_stage(commands[first].name) || commands.back().name != "-o")
        return 0;
    std::vector<std::string> names, unused;
    bool plan = false;
    for (size_t i = first; i + 1 < commands.size(); ++i) {
        if (is_global(commands[i]))
            continue;
        // A cross-frame stage aligns its neighbours to the whole frame.
        if (!is_stage(commands[i].name) || commands[i].has("frames"))
            return 0;
        plan |= stage_of_command(commands[i].name)->kind == mcdn::StageKind::Plan;
        names.push_back(commands[i].name.substr(2));
    }
    // A plan (--denoise) picks its stages itself: alone or not at all.
    if (plan && names.size() != 1)
        return 0;
    std::string error;
    return mcdn::parse_chain(unused, Strutil::join(names, ","), error) ? first : 0;
}

bool run_streamed_chain(Session& s, const std::vector<Command>& commands, size_t first,
                        bool& streamed, std::string& error)
{
    streamed = false;
    for (size_t i = 0; i < first; ++i) {
        const CommandInfo* info = find_command(commands[i].name);
        if (info->run && !info->run(s, commands[i], error))
            return false;
    }
    // The inputs are read a band at a time (the frame is never in memory whole), each band's
    // values checked as it is read.
    mcdn::InputRows rows;
    if (!s.open_rows(rows, error))
        return false;
    const OIIO::ImageSpec& input = rows.spec();
    const mcdn::AovSet aovs = s.aovs();
    const Command& output = commands.back();
    // A multi-part render is written back in its parts, each whole (mcdn::write_image).
    if (!input.get_string_attribute("mcdn:parts").empty()
        && Strutil::iends_with(output.args[0], ".exr")) {
        if (s.verbose)
            std::cerr << "mcdntool: a multi-part output is written whole: the stages run "
                         "command by command\n";
        return true;
    }
    streamed = true;
    mcdn::WriteOptions write;
    if (!write_options_of(output, write, error))
        return false;
    write.history = s.history;

    mcdn::ChainOptions chain;
    chain.aovs = s.aov_spec;
    chain.progress = s.progress();
    mcdn::set_bands_from_environment(chain);
    set_chain_stages(chain, commands, first);
    chain.output_channels_only = write.channels.empty();  // the writer's default
    if (s.verbose && stage_of_command(commands[first].name)->kind == mcdn::StageKind::Plan) {
        mcdn::DenoisePlan plan;
        if (mcdn::plan_denoise(plan, input, s.aov_spec, error, chain.settings))
            std::cerr << "mcdntool: " << commands[first].name << " runs " << plan.describe()
                      << "\n";
    }
    // Converged tiles are counted on the rows as the chain reads them: each band's own rows
    // once (bands start on the tile grid, mcdn/skip.h), through the light pass's reads, which
    // then also read the colour and its variance (a cnn chain's pass reads only the depth).
    mcdn::ConvergedCount converged;
    const bool count = s.verbose && aovs.has(mcdn::Role::ColorVariance);
    int counted_until = input.y;
    mcdn::InputChecks checks;  // over the bands: a halo's repaired tile counts once
    auto read = [&](ImageBuf& band, int y0, int y1, const std::vector<bool>& channels,
                    std::string& read_error) {
        const bool counting = count && y0 == counted_until;
        std::vector<bool> wanted = channels;
        if (counting && !wanted.empty())
            for (mcdn::Role r : { mcdn::Role::Color, mcdn::Role::ColorVariance })
                for (int c : aovs.channels(r))
                    wanted[size_t(c)] = true;
        if (!rows.read(band, y0, y1, read_error, wanted) || !checks.check(band, aovs, read_error))
            return false;
        if (counting) {
            const mcdn::ConvergedCount c = mcdn::count_converged_tiles(band, aovs);
            converged.converged += c.converged;
            converged.tiles += c.tiles;
            counted_until = y1;
        }
        return true;
    };
    OIIO::Timer timer;
    mcdn::RowWriter writer;
    int bands = 0;
    mcdn::BandCounts fell_back;  // the safety nets' counts over the bands
    auto sink = [&](const ImageBuf& band, const OIIO::ROI& own, std::string& sink_error) {
        fell_back.add(band.spec());
        if (bands++ == 0) {
            OIIO::ImageSpec frame = band.spec();
            frame.y = input.y;
            frame.height = input.height;
            // The header goes out before the other bands exist: the first band's safety-net
            // counts do not stand for the frame's there (-v says the frame's; a frame of one
            // band keeps them).
            if (own.ybegin != input.y || own.yend != input.y + input.height)
                mcdn::BandCounts().set(frame);
            if (!writer.open(frame, output.args[0], write, sink_error))
                return false;
        }
        return writer.write_rows(band, own, sink_error);
    };
    if (!mcdn::run_chain(input, read, chain, sink, error, s.nthreads))
        return false;
    if (s.verbose)
        report_repaired_halves(checks.repaired_tiles());
    if (count)
        std::cerr << format("mcdntool: {} of {} tiles converged (docs/skipping.md), passed "
                            "through unless a stage has :skip=0\n",
                            converged.converged, converged.tiles);
    std::vector<std::string> warnings;
    if (!writer.close(error, &warnings))
        return false;
    for (const auto& w : warnings)
        std::cerr << "mcdntool: warning: " << w << "\n";
    if (s.verbose)
        std::cerr << format("mcdntool: {} {}x{} in {} band(s) of rows, written to {}: {:.2f} s\n",
                            Strutil::join(chain.stages, " "), input.width, input.height, bands,
                            output.args[0], timer());
    if (s.verbose) {
        OIIO::ImageSpec frame;
        fell_back.set(frame);
        report_fallback(frame);
    }
    return true;
}

}  // namespace mcdntool
