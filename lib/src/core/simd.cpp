#include "core/simd.h"

#include <cstdlib>
#include <string>

#if MCDN_X86_DISPATCH
#    include <xmmintrin.h>
#endif

namespace mcdn {

Isa detect_isa()
{
    static const Isa isa = [] {
        Isa best = Isa::Baseline;
#if MCDN_X86_DISPATCH
        __builtin_cpu_init();
        if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
            best = Isa::Avx2;
        if (best == Isa::Avx2 && __builtin_cpu_supports("avx512f")
            && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw")
            && __builtin_cpu_supports("avx512dq"))
            best = Isa::Avx512;
#endif
        if (const char* env = std::getenv("MCDN_ISA")) {
            std::string want = env;
            if (want == "baseline")
                best = Isa::Baseline;
            else if (want == "avx2" && best == Isa::Avx512)
                best = Isa::Avx2;
        }
        return best;
    }();
    return isa;
}

#if MCDN_X86_DISPATCH
constexpr unsigned kFtzDaz = 0x8040;  // MXCSR flush-to-zero (bit 15), denormals-are-zero (bit 6)
FlushDenormals::FlushDenormals() : m_saved(_mm_getcsr())
{
    _mm_setcsr(m_saved | kFtzDaz);
}
FlushDenormals::~FlushDenormals()
{
    _mm_setcsr(m_saved);
}
#else
FlushDenormals::FlushDenormals() { }
FlushDenormals::~FlushDenormals() { }
#endif

const char* isa_name(Isa isa)
{
    switch (isa) {
    case Isa::Avx512: return "avx512";
    case Isa::Avx2: return "avx2";
    default: return "baseline";
    }
}

}  // namespace mcdn
