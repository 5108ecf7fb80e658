// "Skip AOVs that are constant" (mcdn/skip.h): a feature channel whose mean and half buffers
// hold one value over the whole frame (a flat albedo, the depth of a backdrop plane) has
// nothing to prefilter and is a zero column of every regression window (f(q) − f(p) = 0),
// which the solve drops anyway (nfor/least_squares.h); nfor and prefilter leave it out.
#pragma once

#include <vector>

#include "core/feature_channels.h"

namespace mcdn {

/// Mean, half A and half B hold one value everywhere (NaN is never constant).
bool is_constant_feature(const FeaturePlanes& feature);
/// Every value of the plane equals its first (false when empty; NaN is never constant).
bool is_constant_plane(const Plane& plane);

/// For features read without their means (FeatureFaces): reads the mean of each whose halves
/// hold one and the same value throughout, the only ones is_constant_feature can find constant.
void read_means_of_constant_halves(std::vector<FeaturePlanes>& features, const OIIO::ImageBuf& src,
                                   const std::vector<FeatureChannel>& channels);

/// Removes the constant features from `features` and, when given, the matching entries of
/// `channels` (same order). Returns how many were removed.
int drop_constant_features(std::vector<FeaturePlanes>& features,
                           std::vector<FeatureChannel>* channels = nullptr);
/// The same on src's spec: constant over the frame when src is a band of one (its frame
/// facts, core/frame_facts.h), else over src's planes.
int drop_constant_features(std::vector<FeaturePlanes>& features,
                           std::vector<FeatureChannel>& channels, const OIIO::ImageSpec& spec);

}  // namespace mcdn
