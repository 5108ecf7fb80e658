// The committed render fixtures, merged the way the front ends merge them (io.h).
#pragma once

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/io.h"

#include "mcdn_test.h"

namespace mcdn_test {

/// A render `prefix`.exr with `prefix`_var.exr and the halves `prefix`_A.exr, `prefix`_B.exr.
inline OIIO::ImageBuf read_render(const std::string& b)
{
    OIIO::ImageBuf merged;
    EXPECT_TRUE(mcdn::read_inputs(merged, { { b + ".exr", mcdn::InputKind::Mean },
                                            { b + "_var.exr", mcdn::InputKind::Variance },
                                            { b + "_A.exr", mcdn::InputKind::HalfA },
                                            { b + "_B.exr", mcdn::InputKind::HalfB } }))
        << merged.geterror();
    return merged;
}

/// tests/data/box16: Blender Cycles 16 spp with variance and both halves (cycles preset).
inline OIIO::ImageBuf box16()
{
    return read_render(test_data("box16/box_0016spp"));
}

/// box16 stacked four times: 64×256, tall enough for bands of whole 32-row tiles whose
/// 96-row halos still cut the frame (the band tests: tests/nfor, tests/sure, tests/mix).
inline OIIO::ImageBuf tall_box16()
{
    OIIO::ImageBuf one = box16();
    OIIO::ImageSpec spec = one.spec();
    spec.height = spec.full_height = 4 * one.spec().height;
    OIIO::ImageBuf tall(spec);
    for (int i = 0; i < 4; ++i)
        EXPECT_TRUE(OIIO::ImageBufAlgo::paste(tall, 0, i * one.spec().height, 0, 0, one));
    return tall;
}

/// tests/data/cornell20: a Tungsten buffer directory (tungsten preset).
inline OIIO::ImageBuf cornell20()
{
    OIIO::ImageBuf merged;
    EXPECT_TRUE(mcdn::read_inputs(merged, { { test_data("cornell20"), mcdn::InputKind::Mean } }))
        << merged.geterror();
    return merged;
}

}  // namespace mcdn_test
