// The library's stages (mcdn/stages.h) as mcdntool commands: --NAME, the stage's settings as
// its modifiers. Denoisers (--prefilter, --nfor, --cnn) queue up; the next command that
// needs pixels runs them, and an Estimator (--sure) takes the queued chain as the denoiser
// whose error it estimates. A Plan (--denoise) runs the stages it picks as these would.
#include <iostream>

#include "mcdn/denoise.h"
#include "mcdn/stages.h"

#include "session.h"

namespace mcdntool {

using OIIO::ImageBuf;

namespace {

const mcdn::StageInfo& stage_of(const Command& c)
{
    return *mcdn::find_stage(c.name.substr(2));
}

// `frames=N` of a cross-frame stage (mcdn::StageInfo::cross_frame): the front end's
// modifier, as mcdntool reads the frames; the rest are the stage's settings, checked by its
// parser (the recipe and Python take the same keys). No side effects, so the same function
// checks the command line before anything runs.
bool settings_of(const Command& c, int& frames, mcdn::Settings& settings, std::string& error)
{
    settings = c.modifiers;
    frames = 0;
    if (c.has("frames")) {
        const std::string text = c.modifier("frames");
        if (text.size() != 1 || text[0] < '0' || text[0] > '4') {
            error = c.name + ":frames=" + text + " must be 0 to 4 (frames on each side)";
            return false;
        }
        frames = text[0] - '0';
        settings.erase("frames");
    }
    const mcdn::StageInfo& stage = stage_of(c);
    if (!stage.check || stage.check(settings, error))
        return true;
    error = c.name + ":" + error;  // "--nfor:window=4 must be ..."
    return false;
}

bool check_stage(const Command& c, std::string& error)
{
    int frames;
    mcdn::Settings settings;
    return settings_of(c, frames, settings, error);
}

/// The neighbouring frames a cross-frame stage reads, kept alive with the stage.
struct Neighbours {
    std::vector<std::shared_ptr<ImageBuf>> previous, next;
    bool read(const Session& s, int frames, std::string& error)
    {
        return frames == 0 || s.read_neighbours(frames, previous, next, error);
    }
    void give_to(mcdn::StageContext& context) const
    {
        for (const auto& f : previous)
            context.previous_frames.push_back(f.get());
        for (const auto& f : next)
            context.next_frames.push_back(f.get());
    }
};

mcdn::StageContext context_of(const Session& s)
{
    mcdn::StageContext context;
    context.aovs = s.aov_spec;
    context.progress = s.progress();
    context.nthreads = s.nthreads;
    return context;
}

// A Denoiser waits in the session's queue; its neighbours are read now and kept with it
// (SURE may run it again).
bool queue_denoiser(Session& s, const Command& c, std::string& error)
{
    const mcdn::StageInfo& stage = stage_of(c);
    int frames;
    mcdn::Settings settings;
    Neighbours neighbours;
    mcdn::StageContext context = context_of(s);
    mcdn::MadeStage made;
    if (!settings_of(c, frames, settings, error) || !neighbours.read(s, frames, error))
        return false;
    neighbours.give_to(context);
    if (!stage.make(made, settings, context, error))
        return false;
    s.prefilters |= stage.changes_features;
    s.features_out |= settings.count("features-out") && settings.at("features-out") != "0";
    s.queue(
        stage.name,
        [run = made.run, neighbours](ImageBuf& dst, const ImageBuf& src, int) {
            return run(dst, src);
        },
        made.reach);
    return true;
}

// An Estimator runs on the image the queued (or already run) denoisers started from.
bool run_estimator(Session& s, const Command& c, std::string& error)
{
    const mcdn::StageInfo& stage = stage_of(c);
    int frames;
    mcdn::Settings settings;
    if (!settings_of(c, frames, settings, error))
        return false;
    mcdn::StageContext context = context_of(s);
    ImageBuf render;
    mcdn::MadeStage made;
    if (!s.take_denoiser_chain(context.denoiser, context.denoiser_radius, render, error)
        || !stage.make(made, settings, context, error))
        return false;
    s.estimated_denoiser = context.denoiser;
    return s.apply_to(
        stage.name, render,
        [&](ImageBuf& dst, const ImageBuf& src, int) { return made.run(dst, src); }, error);
}

bool run_mixer(Session& s, const Command& c, std::string& error)
{
    const mcdn::StageInfo& stage = stage_of(c);
    int frames;
    mcdn::Settings settings;
    mcdn::MadeStage made;
    mcdn::StageContext context = context_of(s);
    context.denoiser = s.estimated_denoiser;
    if (!settings_of(c, frames, settings, error) || !stage.make(made, settings, context, error))
        return false;
    return s.apply(
        stage.name, [&](ImageBuf& dst, const ImageBuf& src, int) { return made.run(dst, src); },
        error);
}

bool run_stage(Session& s, const Command& c, std::string& error);

// The best chain the inputs allow (mcdn/denoise.h), run as the stage commands would run it;
// frames=N goes to its cross-frame stages (the CNN's input combined).
bool run_plan(Session& s, const Command& c, std::string& error)
{
    if (!s.load(error))
        return false;
    mcdn::DenoisePlan plan;
    std::map<std::string, std::string> plan_settings;
    for (const char* key : { "choose", "frames", "extras" })
        if (c.has(key))
            plan_settings[std::string("denoise.") + key] = c.modifier(key);
    if (!mcdn::plan_denoise(plan, s.image().spec(), s.aov_spec, error, plan_settings)) {
        error = c.name + ": " + error;
        return false;
    }
    if (s.verbose)
        std::cerr << "mcdntool: " << c.name << " runs " << plan.describe() << "\n";
    for (const std::string& name : plan.stages) {
        Command step { "--" + name, {}, {} };
        if (mcdn::find_stage(name)->cross_frame && c.has("frames"))
            step.modifiers["frames"] = c.modifier("frames");
        for (const auto& [key, value] : plan.settings)  // choose.with=cnn, cnn.extras=0, ...
            if (key.compare(0, name.size() + 1, name + ".") == 0)
                step.modifiers[key.substr(name.size() + 1)] = value;
        if (!run_stage(s, step, error))
            return false;
    }
    return true;
}

bool run_stage(Session& s, const Command& c, std::string& error)
{
    switch (stage_of(c).kind) {
    case mcdn::StageKind::Denoiser: return queue_denoiser(s, c, error);
    case mcdn::StageKind::Estimator: return run_estimator(s, c, error);
    case mcdn::StageKind::Mixer: return run_mixer(s, c, error);
    case mcdn::StageKind::Plan: return run_plan(s, c, error);
    }
    return false;
}

}  // namespace

const mcdn::StageInfo* stage_of_command(const std::string& name)
{
    return name.compare(0, 2, "--") == 0 ? mcdn::find_stage(name.substr(2)) : nullptr;
}

bool is_stage(const std::string& name)
{
    return stage_of_command(name) != nullptr;
}

std::vector<CommandInfo> stage_commands()
{
    std::vector<CommandInfo> commands;
    for (const mcdn::StageInfo& stage : mcdn::stage_table()) {
        std::vector<std::string> modifiers = stage.keys;
        if (stage.cross_frame)
            modifiers.push_back("frames");
        commands.push_back({ "--" + stage.name, "", modifiers, stage.help, run_stage, false,
                             check_stage, stage.needs });
    }
    return commands;
}

}  // namespace mcdntool
