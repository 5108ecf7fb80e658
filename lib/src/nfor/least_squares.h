// The small solve of the regression: weighted normal equations (X^T W X) b = X^T W y,
// equilibrated and Cholesky-factored in double, dropping columns that are (numerically)
// constant or collinear with the earlier ones, so that a window with a constant, collinear or
// missing feature gets the lower-order fit instead of NaN.
#pragma once

#include <cmath>

#include "core/simd.h"

namespace mcdn {

/// Relative pivot below which a design column is considered dependent on the earlier ones.
/// After equilibration a pivot is 1 - R² of that column against the previous ones. The
/// normal equations are accumulated in float (relative error ~1e-6), so a column explaining
/// less than 1e-5 of its own variance beyond the others is dropped.
constexpr double kPivotTolerance = 1e-5;

/// gram: D×D symmetric (upper triangle used, row-major), rhs: D×3. Writes beta (D×3).
/// Column order matters: [1, dx, dy, features...] drops features before the plane.
template<int D>
MCDN_INLINE void solve_normal_equations(const double* gram, const double* rhs, double* beta)
{
    double scale[D], L[D][D], z[D][3];
    bool keep[D];
    // Jacobi equilibration: the solve sees every column normalised to unit weighted norm,
    // the equivalent of the paper's local [-1, 1] feature normalisation.
    for (int i = 0; i < D; ++i) {
        double g = gram[i * D + i];
        scale[i] = (g > 0 && std::isfinite(g)) ? 1.0 / std::sqrt(g) : 0.0;
    }
    for (int i = 0; i < D; ++i) {
        keep[i] = scale[i] > 0;
        if (!keep[i])
            continue;
        for (int j = 0; j < i; ++j) {
            if (!keep[j])
                continue;
            double s = gram[j * D + i] * scale[i] * scale[j];
            for (int m = 0; m < j; ++m)
                if (keep[m])
                    s -= L[i][m] * L[j][m];
            L[i][j] = s / L[j][j];
        }
        double pivot = 1.0;
        for (int m = 0; m < i; ++m)
            if (keep[m])
                pivot -= L[i][m] * L[i][m];
        if (!(pivot > kPivotTolerance)) {
            keep[i] = false;
            continue;
        }
        L[i][i] = std::sqrt(pivot);
    }
    // Forward then back substitution on the kept columns.
    for (int i = 0; i < D; ++i) {
        if (!keep[i])
            continue;
        for (int c = 0; c < 3; ++c) {
            double s = rhs[i * 3 + c] * scale[i];
            for (int m = 0; m < i; ++m)
                if (keep[m])
                    s -= L[i][m] * z[m][c];
            z[i][c] = s / L[i][i];
        }
    }
    for (int i = D - 1; i >= 0; --i) {
        if (!keep[i]) {
            for (int c = 0; c < 3; ++c)
                beta[i * 3 + c] = 0.0;
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            double s = z[i][c];
            for (int m = i + 1; m < D; ++m)
                if (keep[m])
                    s -= L[m][i] * z[m][c];  // z[m] now holds the solution of column m
            z[i][c] = s / L[i][i];
            beta[i * 3 + c] = z[i][c] * scale[i];
        }
    }
}

}  // namespace mcdn
