// Runtime ISA dispatch for the hot pixel kernels: the build stays portable (no -march), and
// each kernel is compiled three times (AVX-512, AVX2+FMA, baseline) from one inline body.
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#    define MCDN_X86_DISPATCH 1
#    define MCDN_TARGET_AVX512                                                                     \
        __attribute__((                                                                            \
            target("avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,prefer-vector-width=512")))
#    define MCDN_TARGET_AVX2 __attribute__((target("avx2,fma")))
#else
#    define MCDN_X86_DISPATCH 0
#    define MCDN_TARGET_AVX512
#    define MCDN_TARGET_AVX2
#endif
#define MCDN_INLINE inline __attribute__((always_inline))

namespace mcdn {

enum class Isa { Baseline, Avx2, Avx512 };

/// The widest instruction set this CPU runs (MCDN_ISA=baseline|avx2 lowers it, for tests).
Isa detect_isa();
const char* isa_name(Isa isa);

/// exp(-d) for d >= 0 (a patch distance), vectorisable: Cody-Waite reduction and a degree-6
/// polynomial, relative error ~2e-7. Weights below exp(-80) are flushed to 0 (no denormals).
MCDN_INLINE float exp_neg(float d)
{
    float x = d < 87.0f ? -d : -87.0f;
    float t = x * 1.44269504088896341f;
    int n = int(t - 0.5f);  // round to nearest for t <= 0
    float fn = float(n);
    float r = x - fn * 0.693145751953125f - fn * 1.42860682030941723e-6f;
    float p = 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    int32_t bits = (n + 127) << 23;
    float scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return d < 80.0f ? p * scale : 0.0f;
}

/// For its scope, float results below the normal range are flushed to zero and such inputs
/// read as zero (x86 MXCSR FTZ and DAZ), as they were on entry after it. The NL-means and
/// regression kernels run under it: products of an exp(-80)-small weight and a small
/// feature difference are denormal, and each one costs a microcode assist (most of a pass
/// on some windows), while none is large enough to move a sum of weights that holds the
/// centre's. Every run of a kernel is under it, on any thread: the result does not depend
/// on the thread count.
class FlushDenormals {
public:
    FlushDenormals();
    ~FlushDenormals();
    FlushDenormals(const FlushDenormals&) = delete;
    FlushDenormals& operator=(const FlushDenormals&) = delete;

private:
    unsigned m_saved = 0;
};

/// 16 float lanes (GCC vector extension): one zmm under AVX-512, two ymm under AVX2, four
/// xmm in the baseline build. Unaligned, may alias float data.
typedef float vfloat16 __attribute__((vector_size(64), aligned(4), may_alias));
typedef int32_t vint16 __attribute__((vector_size(64), aligned(4), may_alias));
constexpr int kLanes = 16;

MCDN_INLINE vfloat16 load16(const float* p)
{
    return *reinterpret_cast<const vfloat16*>(p);
}
MCDN_INLINE void store16(float* p, vfloat16 v)
{
    *reinterpret_cast<vfloat16*>(p) = v;
}
MCDN_INLINE vfloat16 splat16(float v)
{
    return vfloat16 {} + v;
}

/// exp_neg on 16 lanes.
MCDN_INLINE vfloat16 exp_neg16(vfloat16 d)
{
    const vfloat16 zero = {};
    vfloat16 x = d < 87.0f ? -d : zero - 87.0f;
    vfloat16 t = x * 1.44269504088896341f;
    vint16 n = __builtin_convertvector(t - 0.5f, vint16);
    vfloat16 fn = __builtin_convertvector(n, vfloat16);
    vfloat16 r = x - fn * 0.693145751953125f - fn * 1.42860682030941723e-6f;
    vfloat16 p = zero + 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    vint16 bits = (n + 127) << 23;
    vfloat16 scale = reinterpret_cast<vfloat16&>(bits);
    return d < 80.0f ? p * scale : zero;
}

}  // namespace mcdn
