// The collaborative regression's tile kernel compiled for AVX2, fully unrolled for the
// common design sizes (regression_tile.h); its own translation unit so that a parallel build
// compiles it beside the other instruction sets.
#include "nfor/regression_tile.h"

namespace mcdn {
namespace regression_detail {

#if MCDN_X86_DISPATCH
template <int D>
MCDN_TARGET_AVX2 void tile_avx2(const RegressionInputs& i, Rect t, TileScratch& s, TileResult& r)
{
    regression_tile_impl<D>(i, t, s, r);
}

TileKernel unrolled_kernel_avx2(int num_features)
{
    return select_unrolled(num_features,
                           [](auto d) -> TileKernel { return tile_avx2<decltype(d)::value>; });
}
#else
TileKernel unrolled_kernel_avx2(int)
{
    return nullptr;
}
#endif

}  // namespace regression_detail
}  // namespace mcdn
