// libFuzzer target: AOV resolution. Each line of the input is either an override token
// (`o:role=ch1,ch2,ch3`, `o:preset=tungsten`, `o:extra.NAME=...`, through
// AovSpec::parse_override), a line of the merged buffer's "mcdn:inputs" attribute
// (`i:variance=box_var.exr`), or a channel name of the merged buffer. The spec is then
// resolved against those channels, as every stage does.
#include "mcdn/aov.h"

#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    mcdn::AovSpec spec;
    std::vector<std::string> channels;
    std::string inputs, error;
    for (const auto& line : mcdn_fuzz::lines_of(data, size, 256)) {
        if (line.compare(0, 2, "o:") == 0)
            spec.parse_override(line.substr(2), error);
        else if (line.compare(0, 2, "i:") == 0)
            inputs += line.substr(2) + "\n";
        else
            channels.push_back(line);
    }
    if (channels.empty())
        return 0;
    OIIO::ImageSpec merged(4, 4, int(channels.size()), OIIO::TypeDesc::FLOAT);
    merged.channelnames = channels;
    merged.attribute("mcdn:inputs", inputs);

    mcdn::AovSet set;
    if (!mcdn::resolve_aovs(set, spec, merged, error))
        return 0;
    set.require(
        { mcdn::Role::Color, mcdn::Role::ColorVariance, mcdn::Role::Albedo, mcdn::Role::DepthB },
        merged, error);
    set.has_component_split();
    for (int r = 0; r < mcdn::kRoleCount; ++r)
        for (int c : set.channels(mcdn::Role(r)))
            if (c < 0 || c >= merged.nchannels)
                __builtin_trap();  // a resolved index outside the buffer
    for (const auto& name : channels)
        mcdn::channel_source(merged, name);
    mcdn::channel_list(merged, 3);
    return 0;
}
