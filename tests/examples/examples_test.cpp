// The generated evaluation scenes in examples/generated (one per scene family, rendered by
// training/datagen, not seen in training): NFOR and the CNN make every one of them better
// than the 16-spp render, and their output is finite.
#include <algorithm>
#include <cmath>

#include <OpenImageIO/filesystem.h>

#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/nfor.h"
#include "mcdn_test.h"

using namespace mcdn;

namespace {

std::vector<std::string> example_crops()
{
    std::vector<std::string> dirs;
    const std::string root = std::string(MCDN_SOURCE_DIR) + "/examples/generated";
    std::vector<std::string> entries;
    OIIO::Filesystem::get_directory_entries(root, entries);
    for (const std::string& d : entries)
        if (OIIO::Filesystem::is_directory(d))
            dirs.push_back(d);
    std::sort(dirs.begin(), dirs.end());
    return dirs;
}

double relmse(const ImageBuf& image, const ImageBuf& reference)
{
    AovSet aovs;
    std::string error;
    EXPECT_TRUE(resolve_aovs(aovs, {}, image.spec(), error)) << error;
    AovSet ref_aovs;
    EXPECT_TRUE(resolve_aovs(ref_aovs, {}, reference.spec(), error)) << error;
    MetricsOptions options;
    options.image_channels = aovs.channels(Role::Color);
    options.reference_channels = ref_aovs.channels(Role::Color);
    Metrics m;
    EXPECT_TRUE(compute_metrics(m, image, reference, options, error)) << error;
    EXPECT_TRUE(std::isfinite(m.relmse));
    return m.relmse;
}

}  // namespace

TEST(Examples, EveryFamilyIsDenoisedBetterThanTheRender)
{
    std::vector<std::string> crops = example_crops();
    ASSERT_EQ(crops.size(), 9u) << "one crop per family in examples/generated";
    for (const std::string& dir : crops) {
        const std::string id = OIIO::Filesystem::filename(dir);
        const std::string b = dir + "/" + id + "_0016spp";
        ImageBuf merged;
        ASSERT_TRUE(read_inputs(merged, { { b + ".exr", InputKind::Mean },
                                          { b + "_var.exr", InputKind::Variance },
                                          { b + "_A.exr", InputKind::HalfA },
                                          { b + "_B.exr", InputKind::HalfB } }))
            << merged.geterror();
        ImageBuf reference(dir + "/" + id + "_ref.exr");
        ASSERT_TRUE(reference.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << reference.geterror();
        const double noisy = relmse(merged, reference);
        const double nfor_error = relmse(nfor(merged), reference);
        const double cnn_error = relmse(cnn(merged), reference);
        std::printf("%-16s relMSE render %.4f  NFOR %.4f  CNN %.4f\n", id.c_str(), noisy,
                    nfor_error, cnn_error);
        EXPECT_LT(nfor_error, noisy) << id;
        EXPECT_LT(cnn_error, noisy) << id;
    }
}
