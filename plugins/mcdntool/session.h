// The state one frame's commands work on: the inputs, the AOV spec, and the current image
// (the merged buffer, read lazily at the first command that needs pixels).
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/io.h"

#include "command.h"

namespace mcdntool {

class Session {
public:
    int nthreads = 0;
    bool verbose = false;

    std::vector<mcdn::InputFile> inputs;
    mcdn::AovSpec aov_spec;
    std::vector<std::string> output_channels;  // --ch
    std::string last_reference;                // --metrics REF, for --heatmap

    /// Reads and checks the inputs if not done yet; resolves the AOV set.
    bool load(std::string& error);
    /// Marks the current image stale (a new -i or --aov arrived).
    void invalidate() { m_loaded = false; }

    OIIO::ImageBuf& image() { return m_image; }
    const mcdn::AovSet& aovs() const { return m_aovs; }
    /// Replaces the current image by a stage's result and re-resolves the AOV set.
    bool replace_image(OIIO::ImageBuf result, std::string& error);

private:
    bool m_loaded = false;
    OIIO::ImageBuf m_image;
    mcdn::AovSet m_aovs;
};

/// Built-in command actions (session.cpp).
bool run_input(Session&, const Command&, std::string& error);
bool run_output(Session&, const Command&, std::string& error);
bool run_aov(Session&, const Command&, std::string& error);
bool run_channels(Session&, const Command&, std::string& error);
bool run_info(Session&, const Command&, std::string& error);
bool run_metrics(Session&, const Command&, std::string& error);
bool run_heatmap(Session&, const Command&, std::string& error);

/// Commands of the denoising stages (stages.cpp).
std::vector<CommandInfo> stage_commands();

}  // namespace mcdntool
