// Denoises a render with the installed library's KPCN op and its installed weights; prints
// the version and the error before and after. Exits non-zero when the op fails or does not
// lower the error.
//   consumer RENDER REFERENCE
#include <cstdio>
#include <string>

#include <OpenImageIO/imagebuf.h>

#include <mcdn/cnn.h>
#include <mcdn/metrics.h>
#include <mcdn/version.h>

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::fprintf(stderr, "usage: consumer RENDER REFERENCE\n");
        return 2;
    }
    OIIO::ImageBuf render(argv[1]), reference(argv[2]);
    OIIO::ImageBuf denoised = mcdn::cnn(render, mcdn::CnnOptions());
    if (denoised.has_error()) {
        std::fprintf(stderr, "consumer: %s\n", denoised.geterror().c_str());
        return 1;
    }
    mcdn::Metrics before, after;
    std::string error;
    if (!mcdn::compute_metrics(before, render, reference, {}, error)
        || !mcdn::compute_metrics(after, denoised, reference, {}, error)) {
        std::fprintf(stderr, "consumer: %s\n", error.c_str());
        return 1;
    }
    std::printf("mcdenoise %s: relMSE %.5f -> %.5f\n", mcdn::version(), before.relmse,
                after.relmse);
    return after.relmse < before.relmse ? 0 : 1;
}
