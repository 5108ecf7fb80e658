// The small solve of the regression: weighted normal equations (X^T W X) b = X^T W y,
// equilibrated and Cholesky-factored in double, dropping columns that are (numerically)
// constant or collinear with the earlier ones, so that a window with a constant, collinear or
// missing feature gets the lower-order fit instead of NaN.
//
// The 16 systems of one pixel group are solved together, 8 double lanes at a time: a dropped
// column is a lane mask (its row and column of the factor are 0), so every lane runs the same
// instructions; the square roots are Newton iterations (no libm call, vectorisable).
#pragma once

#include <cstdint>

#include "core/simd.h"

namespace mcdn {

/// Relative pivot below which a design column is considered dependent on the earlier ones.
/// After equilibration a pivot is 1 - R² of that column against the previous ones. The
/// normal equations are accumulated in float (relative error ~1e-6), so a column explaining
/// less than 1e-5 of its own variance beyond the others is dropped.
constexpr double kPivotTolerance = 1e-5;

typedef double vdouble8 __attribute__((vector_size(64)));
typedef int64_t vlong8 __attribute__((vector_size(64)));

/// 1/sqrt(x) for finite x > 1e-300 to double precision: the bit-trick estimate (error < 4%)
/// and four Newton steps (error squares each step: 4e-2, 2e-3, 5e-6, 4e-11, < 1 ulp).
MCDN_INLINE vdouble8 rsqrt8(vdouble8 x)
{
    vlong8 bits = (vlong8)x;  // a cast between vector types of one size keeps the bits
    bits = 0x5FE6EB50C7B537A9LL - (bits >> 1);
    vdouble8 y = (vdouble8)bits;
    const vdouble8 half_x = 0.5 * x;
    for (int k = 0; k < 4; ++k)
        y = y * (1.5 - half_x * y * y);
    return y;
}

/// Solves the 16 systems of one pixel group. `G` holds the accumulators of the regression:
/// row i of the extended product starts at G[row_offset(i)], entries j in [i, D + 3) (design
/// columns, then the 3 colours). Writes beta (D×3, row r = i·3 + c) to `B`; lanes >= `lanes`
/// and non-finite coefficients get 0. Column order matters: [1, dx, dy, features...] drops
/// features before the plane. DT is D when known at compile time, else 0 (D at run time).
template <int DT>
MCDN_INLINE void solve_normal_equations16(int D, const vfloat16* G, vfloat16* B, int lanes)
{
    constexpr int DM = DT > 0 ? DT : 16;
    if constexpr (DT > 0)
        D = DT;
    const int E = D + 3;
    auto row_offset = [E](int i) { return i * E - i * (i - 1) / 2; };
    auto gram = [&](int i, int j, int h) {  // i <= j; j >= D: right-hand side
        const vfloat16& g = G[row_offset(i) + j - i];
        vdouble8 r;
        for (int l = 0; l < 8; ++l)
            r[l] = g[8 * h + l];
        return r;
    };
    const vdouble8 zero = {};
    for (int h = 0; h < 2; ++h) {
        vdouble8 scale[DM], inv_diag[DM], L[DM][DM], z[DM][3];
        vlong8 keep[DM];
        // Jacobi equilibration: the solve sees every column normalised to unit weighted
        // norm, the equivalent of the paper's local [-1, 1] feature normalisation.
        for (int i = 0; i < D; ++i) {
            vdouble8 g = gram(i, i, h);
            vlong8 ok = (g > 1e-300) & (g < 1e300);
            scale[i] = ok ? rsqrt8(ok ? g : 1.0 + zero) : zero;
        }
        for (int i = 0; i < D; ++i) {
            for (int j = 0; j < i; ++j) {
                vdouble8 s = gram(j, i, h) * scale[i] * scale[j];
                for (int m = 0; m < j; ++m)
                    s -= L[i][m] * L[j][m];
                L[i][j] = keep[j] ? s * inv_diag[j] : zero;
            }
            vdouble8 pivot = 1.0 + zero;
            for (int m = 0; m < i; ++m)
                pivot -= L[i][m] * L[i][m];
            keep[i] = (scale[i] > 0.0) & (pivot > kPivotTolerance);
            inv_diag[i] = keep[i] ? rsqrt8(keep[i] ? pivot : 1.0 + zero) : zero;
            for (int j = 0; j < i; ++j)
                L[i][j] = keep[i] ? L[i][j] : zero;
        }
        // Forward then back substitution; dropped columns stay 0.
        for (int i = 0; i < D; ++i)
            for (int c = 0; c < 3; ++c) {
                vdouble8 s = gram(i, D + c, h) * scale[i];
                for (int m = 0; m < i; ++m)
                    s -= L[i][m] * z[m][c];
                z[i][c] = keep[i] ? s * inv_diag[i] : zero;
            }
        for (int i = D - 1; i >= 0; --i)
            for (int c = 0; c < 3; ++c) {
                vdouble8 s = z[i][c];
                for (int m = i + 1; m < D; ++m)
                    s -= L[m][i] * z[m][c];  // z[m] now holds the solution of column m
                z[i][c] = keep[i] ? s * inv_diag[i] : zero;
                vdouble8 beta = z[i][c] * scale[i];
                for (int l = 0; l < 8; ++l) {
                    float b = float(beta[l]);
                    // Finite (NaN fails both) and a lane of the group.
                    B[i * 3 + c][8 * h + l] =
                        (b > -3e38f && b < 3e38f && 8 * h + l < lanes) ? b : 0.0f;
                }
            }
    }
}

}  // namespace mcdn
