#include "memory.h"

#include "session.h"

#include "mcdn/chain.h"
#include "mcdn/stages.h"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <malloc.h>
#include <sstream>
#include <thread>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

namespace mcdntool {

using OIIO::Strutil::fmt::format;

namespace {

// A stage command's settings (mcdn/stages.h), without the front end's frames=N.
mcdn::Settings settings_of(const Command& c)
{
    mcdn::Settings settings = c.modifiers;
    settings.erase("frames");
    return settings;
}

// Bytes of the stage that holds the most besides the frame buffers (the networks'), on
// `threads` threads: stages run one after the other.
double held_bytes(const std::vector<Command>& commands, int threads)
{
    double most = 0;
    for (const auto& c : commands)
        if (const mcdn::StageInfo* stage = stage_of_command(c.name); stage && stage->held_bytes)
            most = std::max(most, stage->held_bytes(settings_of(c), threads));
    return most;
}

}  // namespace

void keep_freed_memory()
{
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, -1);
}

double estimated_peak_bytes(const std::vector<Command>& commands, double pixels, int channels,
                            int threads, double band_pixels)
{
    double frames = 0;
    for (const auto& c : commands) {
        if (const mcdn::StageInfo* stage = stage_of_command(c.name))
            frames += stage->frame_buffers;
        // Cross-frame (--nfor, --cnn, --denoise): the neighbours' merged inputs, held while
        // the stage runs.
        if (c.has("frames"))
            frames += 2 * std::max(0.0, OIIO::Strutil::stod(c.modifier("frames")));
    }
    const double stage_pixels = band_pixels > 0 ? std::min(pixels, band_pixels) : pixels;
    // The merged input, then the stages' buffers of a band (or of the frame).
    return (pixels + frames * stage_pixels) * channels * sizeof(float)
           + held_bytes(commands, threads);
}

bool available_bytes(double& bytes, std::string& error)
{
    // A farm slot's own limit, for jobs that may use less than the machine has.
    if (const char* limit = std::getenv("MCDN_MEMORY_LIMIT"); limit && *limit) {
        std::string text = limit;
        double scale = 1;
        switch (text.back()) {
        case 'G':
        case 'g':
            scale = 1e9;
            text.pop_back();
            break;
        case 'M':
        case 'm':
            scale = 1e6;
            text.pop_back();
            break;
        default: break;
        }
        if (!OIIO::Strutil::string_is_float(text) || OIIO::Strutil::stod(text) < 0) {
            error = format("MCDN_MEMORY_LIMIT={}: needs a number of bytes, or one with a G or "
                           "M suffix (16G)",
                           limit);
            return false;
        }
        bytes = OIIO::Strutil::stod(text) * scale;
        return true;
    }
    std::ifstream meminfo("/proc/meminfo");
    std::string line;
    double kb = 0;
    while (std::getline(meminfo, line)) {
        std::istringstream in(line);
        std::string key;
        double value = 0;
        in >> key >> value;
        if (key == "MemAvailable:" || key == "SwapFree:")
            kb += value;
    }
    bytes = kb * 1024.0;
    // A container's (cgroup v2) limit, where one is set.
    std::ifstream max_file("/sys/fs/cgroup/memory.max"),
        current_file("/sys/fs/cgroup/memory.current");
    std::string max_text;
    double current = 0;
    if (max_file >> max_text && max_text != "max" && current_file >> current
        && OIIO::Strutil::string_is_float(max_text))
        bytes = std::min(bytes, std::max(0.0, OIIO::Strutil::stod(max_text) - current));
    return true;
}

bool check_memory(const std::vector<Command>& commands, int threads, int parallel_frames,
                  std::string& error)
{
    // The frame the inputs describe, from their headers alone, and the channels read at
    // least: every channel of a render (-i, -i:as=mean), the colour's face of a variance or
    // half file (the reader takes only the roles' faces of those: mcdn::InputSelection).
    double pixels = 0, width = 0;
    int channels = 0, in_files = 0;
    OIIO::ImageSpec first_spec;  // the first input's: the stages' reach on its channels
    for (const auto& c : commands) {
        if (c.name != "-i")
            continue;
        auto in = OIIO::ImageInput::open(c.args[0]);
        if (!in) {
            // A directory, or unreadable: reading will say, naming the file. OIIO's message
            // is taken here, or it would print it at exit without the name ("Subsampled
            // channels are not supported").
            OIIO::geterror();
            return true;
        }
        const std::string kind = c.modifier("as", "mean");
        int file_channels = 0;
        for (int s = 0; in->seek_subimage(s, 0); ++s) {
            const OIIO::ImageSpec& spec = in->spec();
            if (first_spec.width == 0)
                first_spec = spec;
            pixels = std::max(pixels, double(spec.width) * spec.height);
            width = std::max(width, double(spec.width));
            file_channels += spec.nchannels;
        }
        in_files += file_channels;
        // K seeds are read whole, then combined into the mean, its variance and halves:
        // K + 4 frames of their channels, at most 3 a seed (K = 2).
        channels += kind == "mean"   ? file_channels
                    : kind == "seed" ? 3 * file_channels
                                     : std::min(file_channels, 3);
    }
    double available = 0;
    if (!available_bytes(available, error))
        return false;
    if (pixels == 0 || available == 0)  // no /proc/meminfo: nothing to compare with
        return true;
    if (threads <= 0)
        threads = int(std::max(1u, std::thread::hardware_concurrency()));
    const int frames_at_once = std::max(1, parallel_frames);
    const int per_frame_threads = std::max(1, threads / frames_at_once);
    // A streamed chain's band (mcdn::chain_band) and its halo each side. A plan (--denoise)
    // picks its stages on the merged input, which the first file does not describe: a reach
    // of 160 rows, its reach with halves.
    double band = 0;
    if (const size_t first_stage = streamed_chain_start(commands)) {
        mcdn::ChainOptions chain;
        mcdn::set_bands_from_environment(chain);
        set_chain_stages(chain, commands, first_stage);
        const mcdn::StageInfo* stage = mcdn::find_stage(chain.stages[0]);
        const bool plan = stage && stage->kind == mcdn::StageKind::Plan;
        const int reach = plan ? -1 : mcdn::chain_reach(first_spec, chain);
        const mcdn::ChainBand cut = mcdn::chain_band(int(width), chain, reach >= 0 ? reach : 160);
        band = double(cut.own_pixels) + 2.0 * cut.halo_rows * width;
    }
    const double need =
        frames_at_once * estimated_peak_bytes(commands, pixels, channels, per_frame_threads, band);
    if (need <= available)
        return true;
    const double gb = 1e9;
    const double one_thread =
        frames_at_once * estimated_peak_bytes(commands, pixels, channels, 1, band);
    std::string advice =
        one_thread <= available
            ? format("--threads {} needs about {:.1f} GB", frames_at_once, one_thread / gb)
            : "fewer input channels (only the files and AOVs the chain "
              "reads), a shorter chain or a smaller frame would need less";
    if (frames_at_once > 1)
        advice += "; --parallel-frames 1 runs one frame at a time";
    error = format("a {:.0f} Mpixel frame with {} channels ({} read at least) needs about "
                   "{:.1f} GB for this chain and {} thread(s), {:.1f} GB are available: {}",
                   pixels / 1e6, in_files, channels, need / gb, per_frame_threads, available / gb,
                   advice);
    return false;
}

}  // namespace mcdntool
