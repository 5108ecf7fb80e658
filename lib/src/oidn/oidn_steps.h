// The steps of the oidn op (mcdn/oidn.h): Open Image Denoise's published networks read from
// their own weight files and run on our engine (nn/nn.h), with OIDN's input transforms.
// Everything here is written from the public facts of OIDN's repository (its `.tza` layout,
// the UNet's tensor names and shapes, the transfer function's constants): no OIDN code.
#pragma once

#include <algorithm>
#include <cfloat>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "nn/nn.h"

namespace mcdn {
namespace oidn_net {

/// Reads a tensor archive (`.tza`, OIDN's weight files) into `weights`, every tensor as
/// float32 (its half floats widened), names and OIHW shapes as stored. The layout, every
/// integer little-endian:
///   header   uint16 magic 0x41D7, uint8 major version (2), uint8 minor, uint64 offset of
///            the table
///   table    uint32 tensor count, then per tensor: uint16 name length, the name, uint8
///            rank, rank × uint32 dims (outermost first), rank layout letters ("oihw",
///            "x"), one data type letter ('f' float32, 'h' float16), uint64 offset of its
///            data (row-major)
/// False with a one-line `error` naming the file and what is wrong.
bool read_tza(const std::string& path, nn::Weights& weights, std::string& error);

/// OIDN's UNet ("rt" filters) built from the archive's tensors: 3×3 convolutions
/// enc_conv0, enc_conv1 (then a 2×2 max-pool: pool1), enc_conv2 (pool2), enc_conv3 (pool3),
/// enc_conv4 (pool4), enc_conv5a, enc_conv5b; then three times a nearest 2× upsampling
/// joined (channels after) by pool3, pool2, pool1 into dec_conv4a/4b, 3a/3b, 2a/2b; a last
/// upsampling joined by the input into dec_conv1a/1b; dec_conv0. ReLU after every
/// convolution (the output's is the clamp at 0 the inverse transfer applies anyway).
/// Channel counts come from the tensors' shapes; the input's is enc_conv0's. False with
/// `error` when a tensor is missing or its shape does not chain.
bool build_unet(nn::Net& net, const nn::Weights& weights, std::string& error);

/// OIDN's HDR transfer: the PU curve (Aydin et al. 2008's fit of perceptually uniform
/// encoding, as OIDN defines it) normalised so that 65504 maps to 1; its inverse.
float pu_forward(float y);
float pu_inverse(float x);

/// OIDN's low-dynamic-range transfer, which its albedo prefilter (rt_alb) reads and writes
/// through: the sRGB curve (IEC 61966-2-1) on [0, 1]; its inverse.
float srgb_forward(float y);
float srgb_inverse(float x);

}  // namespace oidn_net
}  // namespace mcdn
