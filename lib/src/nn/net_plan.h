// How a Net runs, decided once when its state is made (Net::make_state): the fusions, the
// views and when each value's storage goes back for reuse. Net::run is then its input
// checks and a loop over these steps (net_run.cpp).
#pragma once

#include <vector>

#include "nn/nn.h"

namespace mcdn {
namespace nn {

/// One node of the network as it runs.
struct Step {
    enum class Kind {
        conv,      ///< a convolution into fresh storage
        conv_sum,  ///< a convolution summed into its residual (the add that follows
                   ///< it fused: oneDNN's sum post-op), into a copy of the residual
                   ///< or, `in_place`, into the residual's own storage
        take,      ///< the add a conv_sum made: the conv's result, handed on
        add,       ///< a + b, then the activation
        max_pool2,
        upsample2,
        concat,
        slice,              ///< channels copied out
        view,               ///< channels read where they are (by apply_kernel)
        apply_kernel,       ///< kernels from logits (a value, or a view of one)
        apply_kernel_head,  ///< kernels whose logits the fused 1×1 conv `head` makes per tap
        upconv,  ///< a 3×3 conv of concat(upsample2(x), skip), neither made (UpConvLayer),
                 ///< through scratch storage (scratch_slot)
    };
    Kind kind = Kind::conv;
    int id = -1;            ///< the node it computes
    int other = -1;         ///< conv_sum: the residual; take: the conv; view: the sliced
                            ///< value; apply_kernel_head: the 1×1 conv
    bool in_place = false;  ///< conv_sum: into the residual's storage
    Activation after_sum = Activation::none;  ///< conv_sum: the fused add's activation
    int first_channel = 0;        ///< apply_kernel(_head): the logits' first channel in `other`
    std::vector<int> free_after;  ///< values whose storage is free once this step has run
    int slot = -1;                ///< the storage slot its value is computed into (StoragePlan)
    int scratch_slot = -1;        ///< upconv: the slot of its phase scratch, free after it
    /// concat: the inputs read through an upsample2 that has no step of its own (fused:
    /// the concat reads the upsample's input at half resolution), one flag per input.
    std::vector<char> upsampled;
};

/// Where the values live, decided with the steps: each step that computes into fresh storage
/// takes a slot (Step::slot), which holds one value at a time and is sized for the largest
/// it ever holds. Sizes are per pixel of the network's input (a value of c channels at scale
/// s is c / s² floats a pixel), so one plan serves every tile size. A value handed on (take,
/// an in-place conv_sum) keeps its slot; an output's slot is where the caller's returned
/// output goes back.
struct StoragePlan {
    std::vector<double> slot_floats;  ///< each slot's size, floats per input pixel
    std::vector<int> output_slot;     ///< each output's slot (-1: an input, or output twice)
};

/// The steps of `nodes` with `outputs` kept to the end; `fuse` (the oneDNN backend) folds
/// residual adds into their convolutions, reads kernel logits in place, fuses 1×1 kernel
/// heads and upsamplings into the concat that reads them, and a 3×3 conv of such a concat
/// into the conv (upconv); the reference backend runs every node as written.
std::vector<Step> plan_steps(const std::vector<Net::Node>& nodes, const std::vector<int>& outputs,
                             bool fuse);

/// The slots of `steps` (setting each Step::slot and scratch_slot), by following their births,
/// hand-overs and frees in order: a value takes the smallest free slot that holds it, else the
/// largest free slot (grown to it), else a new one. Peak memory then stays near the widest moment
/// of the network instead of every size it ever freed.
StoragePlan plan_storage(std::vector<Step>& steps, const std::vector<Net::Node>& nodes,
                         const std::vector<int>& outputs);

/// True when the step computes its value into fresh storage (Step::slot's).
bool computes_into_storage(const Step& step);

}  // namespace nn
}  // namespace mcdn
