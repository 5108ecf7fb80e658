// The steps of the progressive mix (PD §4), one file each: the analytic alpha (eq. 9),
// the network's alpha (§4.3), and the t-test bound (eq. 12-18).
#pragma once

#include <string>

#include "skip/converged_tiles.h"
#include "core/planar.h"
#include "mcdn/mix.h"
#include "nn/nn.h"

namespace mcdn {

/// What the mix reads, one plane per colour channel.
struct MixInputs {
    Plane x[3], y[3], variance[3], sure[3], divergence[3], residual[3];
};

/// Eq. 9 with box-averaged terms, clipped to [0, 1].
void analytic_alpha(Plane alpha[3], const MixInputs& in, int radius);

/// §4.3: builds h_NN and loads its weights file (names, shapes and the input-layout tag of
/// its metadata checked). On failure a one-line error naming the file and what to do.
bool load_mix_net(nn::Net& net, const std::string& path, std::string& error);

/// The network's 18 inputs (training/mix/model.py features()), NHWC.
nn::Tensor net_features(const MixInputs& in);
/// The same for the pixels of `window` into f (reshaped), of the frame extended past its last
/// row and column by repeating them, as nn::run_tiled extends it.
void net_features(const MixInputs& in, const Rect& window, nn::Tensor& f);

/// alpha = clip(f_act(h_NN(features)), 0, 1) per colour channel (eq. 19); `raw`, if given,
/// receives the network's outputs (x1 RGB, x2 RGB, x3 RGB per pixel).
/// `regions`: only these are computed (nn::TileOptions::regions), alpha = 0 elsewhere.
bool net_alpha(Plane alpha[3], const MixInputs& in, nn::Net& net, std::string& error,
               nn::Tensor* raw = nullptr, const std::vector<Rect>& regions = {});

/// The tiles where z = x whatever α is (MixOptions::skip): y = x throughout (the denoiser
/// passed them through, as the ops do with converged tiles).
ConvergedTiles tiles_mixing_to_x(const MixInputs& in, const SkipOptions& skip);

/// Where variance > relative_variance * (y^2 + 0.01) (the render is an outlier of its own
/// variance, past where the network's arctan inputs saturate), alpha >= the pixel's eq. 9,
/// clipped to [0, 1]; where variance > drop_relative_variance * (y^2 + 0.01), alpha = 1;
/// elsewhere alpha is left alone (outlier_floor.cpp says why). 0 turns a rule off.
void outlier_floor(Plane& alpha, const Plane& variance, const Plane& y, const Plane& divergence,
                   const Plane& residual, float relative_variance, float drop_relative_variance);

/// sigma_s of eq. 15: min(sqrt(spatial variance of x), 1) * scale, x the channels
/// `x_channels` of the whole of src (read a few rows at a time; src's frame facts when it is
/// a band of a larger frame, core/frame_facts.h).
float t_test_sigma(const OIIO::ImageBuf& src, const int x_channels[3], float scale);

/// alpha' of one band: the model's alpha (`net` for Model::Net, loaded by load_mix_net),
/// the t-test bound with the frame's sigma_s, 0 on `passed` (set to tiles_mixing_to_x).
bool mix_alpha(Plane alpha[3], ConvergedTiles& passed, const MixInputs& in,
               const MixOptions& options, nn::Net* net, float sigma_s, std::string& error);

/// Eq. 12-18: scales alpha by 1 - S(a(|t| - c)) in place.
void t_test_bound(Plane& alpha, const Plane& x, const Plane& y, const Plane& variance,
                  float sigma_s, const MixOptions& options);

/// Mean over a (2r+1)^2 box clipped to the image (separable, in double).
Plane box_mean(const Plane& in, int radius);

}  // namespace mcdn
