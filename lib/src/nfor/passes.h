// NFOR's passes (NFOR §5.2-5.4), the steps nfor.cpp runs in the paper's order.
#pragma once

#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "ops/color_planes.h"
#include "core/feature_channels.h"
#include "core/frame_facts.h"
#include "core/planar.h"
#include "mcdn/nfor.h"
#include "nfor/extras_regression.h"
#include "nfor/neighbour_frames.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// §5.2's cross-filtered fits of each half for both candidate bandwidths.
struct FirstPass {
    std::vector<Plane> fit_a[2], fit_b[2];
};

/// The probe step of the one-buffer SURE, relative to the render's scale as in the sure op
/// (SureOptions::epsilon_relative): eps sqrt(Var) moves a pixel of
/// mean standard deviation by 1e-3 of the mean |x|.
/// Where the probes' index space starts: one-buffer NFOR draws b of a pixel by its index in
/// the frame (of a band's frame, core/frame_facts.h), and takes the frame's probe step.
struct ProbeIndex {
    const FrameFacts* facts = nullptr;
    uint64_t first = 0;
    ColorSums color;  // the frame's (facts->colour), else the planes' as read
};

/// §5.3's result: the candidates blended per pixel, which is what §5.4 filters, and the
/// blended MSE estimate and selection map when asked for.
struct Selected {
    Plane combined[3], combined_variance[3];
    std::vector<Plane> mse, selection;
    ConvergedTiles fallback;  // the safety net's tiles (skip/worse_tiles.h)
};

/// §5.2: half A fitted with the features and colour weights of half B, and vice versa, for
/// each candidate bandwidth. The features' halves are not needed after it.
FirstPass first_pass(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                     const std::vector<NeighbourFrame>& neighbours, ExtraAovs& extras,
                     const NforOptions& options, const ConvergedTiles& converged, int nthreads);

/// §5.3 by the two-buffer estimate: each candidate's MSE from the other half. The colour's
/// halves are not needed after it.
void two_buffer_mse(std::vector<Plane> mse[2], ColorPlanes& color, const FirstPass& pass);

/// The one-buffer first pass (no half buffers): the render fitted with its own weights, and
/// once more probed, so that §5.3 picks by SURE (PD §2.3); `mse` the candidates' SURE.
FirstPass first_pass_one_buffer(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                                const std::vector<NeighbourFrame>& neighbours, ExtraAovs& extras,
                                const NforOptions& options, const ConvergedTiles& converged,
                                int nthreads, std::vector<Plane> mse[2],
                                const ProbeIndex& probe_index);

/// §5.3: the MSE estimates filtered, the lower picked per pixel, the selection filtered and
/// the candidates blended with it; the safety net's tiles.
Selected select_bandwidths(const ImageBuf& src, ColorPlanes& color, std::vector<Plane> mse[2],
                           FirstPass& pass, ExtraAovs& extras, const NforOptions& options,
                           const ConvergedTiles& converged, int nthreads);

/// §5.4: the combined halves filtered once more, guided by themselves, with the mean
/// features.
std::vector<Plane> second_pass(Selected& selected, std::vector<FeaturePlanes>& features,
                               ExtraAovs& extras, const NforOptions& options,
                               const ConvergedTiles& converged, int nthreads);

}  // namespace mcdn
