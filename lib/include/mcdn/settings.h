// Stage options from text settings, the form every front end receives them in: mcdntool's
// modifiers (--nfor:window=19), the format plugin's recipe and run_chain (nfor.window=19),
// Python's keyword arguments. One parser per stage, so each front end accepts the same keys
// with the same checks and the same defaults (the Options' own): here for the stages whose
// Options the front ends also build themselves (Python's single-stage functions); a stage
// reached only by name (oidn, choose) parses in its stage-table entry (StageInfo::check).
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "mcdn/cnn.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/sure.h"

namespace mcdn {

/// One stage's settings, key -> value as typed: {"window": "19", "k": "0.5,1.0"}.
using Settings = std::map<std::string, std::string>;

/// The keys a stage accepts ("prefilter", "nfor", "cnn", "sure", "mix"); empty for others.
const std::vector<std::string>& setting_keys(const std::string& stage);

/// Fill the Options from the settings; keys that are absent keep their value. False with
/// `error` ("window=4 must be an odd width between 1 and 101": the front end puts its own
/// prefix, --nfor: or nfor., before it) on an unknown key or a value out of range.
/// Windows and patches are widths (odd, as the papers write 19×19), the Options radii.
bool apply_settings(PrefilterOptions& options, const Settings& settings, std::string& error);
bool apply_settings(NforOptions& options, const Settings& settings, std::string& error);
bool apply_settings(CnnOptions& options, const Settings& settings, std::string& error);
bool apply_settings(SureOptions& options, const Settings& settings, std::string& error);
bool apply_settings(MixOptions& options, const Settings& settings, std::string& error);

/// The settings of one stage out of "stage.key" settings: {"nfor.window": "19"} -> {"window":
/// "19"}.
Settings stage_settings(const std::map<std::string, std::string>& all, const std::string& stage);

/// True when `text` is a number within float range (nan and inf would reach the ops as NaN).
bool parse_finite(const std::string& text, double& value);

/// Denoisers run one after the other as one Denoiser (what SURE probes); a failing stage's
/// error is reported as "name: error".
Denoiser compose(std::vector<std::pair<std::string, Denoiser>> stages);
/// The same for stages that may run in place (dst and src one buffer, as every mcdn op
/// may): each stage after the first runs on the result before it, no frame-sized copy;
/// called with dst and src one buffer, the first runs in it too.
Denoiser compose_in_place(std::vector<std::pair<std::string, Denoiser>> stages);

/// How far one denoiser of a chain reaches (its stage's receptive_radius()): on an input not
/// yet prefiltered and on one that is; -1 when not known (the cnn, a callable).
struct StageReach {
    int radius = -1, prefiltered_radius = -1;
    bool prefilters = false;  // its output is prefiltered (the prefilter stage)
};
StageReach stage_reach(const PrefilterOptions& options);
StageReach stage_reach(const NforOptions& options);
StageReach stage_reach(const CnnOptions& options);

/// How far a chain of denoisers reaches, for SureOptions::denoiser_radius: the sum of its
/// stages' reach, each on the input it gets; -1 when any stage's is not known.
int chain_radius(const std::vector<StageReach>& stages);

}  // namespace mcdn
