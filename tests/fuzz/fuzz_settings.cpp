// libFuzzer target: the option values every front end hands the library (mcdntool's
// :modifiers, recipe stage.key= settings, Python's keyword arguments all go through
// mcdn::apply_settings, parse_threads and check_compression). Each line is `stage.key=value`
// (stage: prefilter, nfor, cnn, sure, mix), `threads=N` or `compression=NAME`; accepted
// values must be in the ranges the ops check.
#include "mcdn/io.h"
#include "mcdn/settings.h"
#include "mcdn/threads.h"

#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    std::map<std::string, std::string> all;
    std::string error;
    for (const auto& line : mcdn_fuzz::lines_of(data, size, 128)) {
        size_t eq = line.find('=');
        if (eq == std::string::npos)
            continue;
        std::string key = line.substr(0, eq), value = line.substr(eq + 1);
        if (key == "threads") {
            int n = -1;
            if (mcdn::parse_threads(value, n, error) && (n < 0 || n > mcdn::kMaxThreads))
                __builtin_trap();  // accepted outside the rule
        } else if (key == "compression")
            mcdn::check_compression(value, error);
        else
            all[key] = value;
    }
    mcdn::PrefilterOptions prefilter;
    mcdn::NforOptions nfor;
    mcdn::CnnOptions cnn;
    mcdn::SureOptions sure;
    mcdn::MixOptions mix;
    mcdn::apply_settings(prefilter, mcdn::stage_settings(all, "prefilter"), error);
    mcdn::apply_settings(nfor, mcdn::stage_settings(all, "nfor"), error);
    mcdn::apply_settings(cnn, mcdn::stage_settings(all, "cnn"), error);
    if (mcdn::apply_settings(sure, mcdn::stage_settings(all, "sure"), error)
        && !(sure.epsilon_relative > 0 && sure.epsilon_relative <= mcdn::kMaxEpsilonRelative))
        __builtin_trap();  // a probe step the op would refuse, accepted by the parser
    mcdn::apply_settings(mix, mcdn::stage_settings(all, "mix"), error);
    return 0;
}
