// What the stage table's entries share (lib/src/chain/stage_table.cpp, NFOR's and the
// networks' entries and the table itself; stage_table_pd.cpp, Progressive Denoising's):
// settings into Options, what a stage reads, and the entries each file makes for the other.
#pragma once

#include <string>

#include "mcdn/settings.h"
#include "mcdn/stages.h"

namespace mcdn {
namespace stage_entries {

// ---- settings -> Options --------------------------------------------------------------

template <class Options> bool check_settings(const Settings& settings, std::string& error)
{
    Options o;
    return apply_settings(o, settings, error);
}

// The Options of a stage from valid settings and what the front end gives every stage.
template <class Options>
bool options_of(Options& o, const Settings& settings, const StageContext& context,
                std::string& error)
{
    if (!apply_settings(o, settings, error))
        return false;
    o.aovs = context.aovs;
    o.progress = context.progress;
    return true;
}

template <class Options> StageReach reach_of(const Settings& settings, const std::string&)
{
    Options o;
    std::string error;
    return apply_settings(o, settings, error) ? stage_reach(o) : StageReach();
}

// ---- what each stage reads ------------------------------------------------------------

inline bool has_features(const AovSet& aovs)
{
    for (Role r : { Role::Albedo, Role::Normal, Role::Depth, Role::Visibility })
        if (aovs.has(r))
            return true;
    return false;
}


inline bool has_halves(const AovSet& aovs)
{
    return aovs.has(Role::ColorA) && aovs.has(Role::ColorB);
}

// NFOR's stages (stage_table.cpp), which choose runs itself.
bool make_prefilter(MadeStage& made, const Settings& settings, const StageContext& context,
                    std::string& error);
bool make_nfor(MadeStage& made, const Settings& settings, const StageContext& context,
               std::string& error);

// Progressive Denoising's stages (stage_table_pd.cpp).
StageInfo sure_stage();
StageInfo choose_stage();
StageInfo mix_stage();

}  // namespace stage_entries
}  // namespace mcdn
