// libFuzzer target: EXR files as renderers and tools write them (scanline, tiled with 1x1,
// 4x1 and 1x4 tiles, MIP-mapped, multi-part; corpus/exr), mutated. Each is read as mcdntool
// reads an input (headers, then every pixel) and, where the reader accepts it, written back
// through the writer every front end uses: what the reader accepts the writer must write
// (it once kept a tiled input's tiles and then wrote scanlines). Nothing may crash, hang or
// allocate without bound.
#include <cstdio>
#include <cstdlib>
#include <string>

#include <unistd.h>

#include <OpenImageIO/imageio.h>

#include "mcdn/io.h"

namespace {

// A folder of this process's own for the file under test and its output.
const std::string& work_dir()
{
    static const std::string dir = [] {
        char name[] = "/tmp/mcdn_fuzz_exr_XXXXXX";
        const char* made = ::mkdtemp(name);
        if (!made)
            std::abort();
        return std::string(made);
    }();
    return dir;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
    // One thread each: thread pools started per file are most of an input's time otherwise.
    OIIO::attribute("threads", 1);
    OIIO::attribute("exr_threads", -1);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::string in = work_dir() + "/in.exr", out = work_dir() + "/out.exr";
    FILE* f = std::fopen(in.c_str(), "wb");
    if (!f)
        std::abort();
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    mcdn::InputRows rows;
    std::string error;
    if (!rows.open({ mcdn::InputFile(in) }, mcdn::InputSelection(), error))
        return 0;
    const OIIO::ImageSpec& spec = rows.spec();
    // Bounded work per input: a header may claim any size.
    if (int64_t(spec.width) * spec.height * spec.nchannels > (int64_t(1) << 18))
        return 0;
    OIIO::ImageBuf frame;
    if (!rows.read(frame, spec.y, spec.y + spec.height, error))
        return 0;  // corrupt pixels: an error, as it should be
    mcdn::WriteOptions options;
    options.software.clear();
    if (!mcdn::write_image(frame, out, options, error)) {
        std::fprintf(stderr, "read but not written: %s\n", error.c_str());
        __builtin_trap();
    }
    return 0;
}
