// Net::run (nn.h): its input checks, then the steps its plan decided (net_plan.h), each
// value's storage taken from values freed earlier, this run or the last.
#include <algorithm>
#include <cmath>

#include "nn/net_plan.h"
#include "nn/onednn_conv.h"
#include "nn/ops.h"
#include "core/huge_pages.h"

namespace mcdn {
namespace nn {

namespace {

/// Storage for `size` floats: the smallest spare buffer that holds it, or none (then the
/// op allocates). A buffer is never grown, as two values could then trade buffers and grow
/// them at every tile; run_tiled runs its largest tiles first, so every value of the later
/// tiles finds a buffer.
std::vector<float> take_storage(std::vector<std::vector<float>>& spare, size_t size)
{
    size_t best = spare.size();
    for (size_t i = 0; i < spare.size(); ++i)
        if (spare[i].capacity() >= size
            && (best == spare.size() || spare[i].capacity() < spare[best].capacity()))
            best = i;
    if (best == spare.size())
        return {};
    std::vector<float> storage = std::move(spare[best]);
    spare.erase(spare.begin() + best);
    return storage;
}

/// The values of one run: owned[id] holds what node id computed (or nothing: an input, a
/// view), value[id] where its values are, home[id] the slot its storage goes back to.
struct Values {
    std::vector<Tensor> owned;
    std::vector<const Tensor*> value;
    std::vector<int> home;
    std::vector<std::vector<float>>& slots;
    const StoragePlan& plan;
    std::vector<std::vector<float>>& spare;
    int height, width;

    /// Storage for `floats` a pixel in `slot`: the slot's own, else a spare, reserved for the
    /// largest value the slot holds (tiles run largest first: later tiles allocate nothing);
    /// without a slot (-1), a spare or nothing (the op allocates).
    std::vector<float> storage(int slot, double floats)
    {
        const size_t pixels = size_t(height) * width;
        std::vector<float> storage;
        if (slot >= 0 && slots[size_t(slot)].capacity() > 0)
            storage = std::move(slots[size_t(slot)]);
        else
            storage = take_storage(spare, size_t(std::ceil(floats * pixels)));
        if (slot >= 0) {
            const size_t planned = size_t(std::ceil(plan.slot_floats[size_t(slot)] * pixels));
            if (storage.capacity() < planned) {
                storage = std::vector<float>();  // grown without copying values nobody reads
                storage.reserve(planned);
                advise_huge_pages(storage.data(), planned * sizeof(float));
            }
        }
        return storage;
    }

    /// owned[id] with its slot's storage (storage()), reshaped by the op.
    Tensor& fresh(const Step& step, const Net::Node& node)
    {
        owned[size_t(step.id)].data =
            storage(step.slot, double(node.channels) / (double(node.scale) * node.scale));
        home[size_t(step.id)] = step.slot;
        return owned[size_t(step.id)];
    }

    /// The phase scratch of an upconv step (a quarter of its output), in its own slot.
    Tensor scratch(const Step& step, const Net::Node& node)
    {
        Tensor t;
        t.data =
            storage(step.scratch_slot, double(node.channels) / (4.0 * node.scale * node.scale));
        return t;
    }

    /// An upconv's scratch back to its slot.
    void release_scratch(const Step& step, Tensor& t)
    {
        slots[size_t(step.scratch_slot)] = std::move(t.data);
    }

    /// id's storage back to its slot (or, where that has storage, to the spares).
    void release(int id)
    {
        Tensor& t = owned[size_t(id)];
        const int slot = home[size_t(id)];
        home[size_t(id)] = -1;
        if (t.data.capacity() > 0 && slot >= 0 && slots[size_t(slot)].capacity() == 0)
            slots[size_t(slot)] = std::move(t.data);
        else if (t.data.capacity() > 0)
            spare.push_back(std::move(t.data));
        t = Tensor();
    }
};

/// Runs one step of the oneDNN backend (`fast`) or of the reference loops.
void run_step(const Step& step, const std::vector<Net::Node>& nodes, NetState& state,
              const std::vector<std::vector<float>>& weights,
              const std::vector<std::vector<float>>& biases, bool fast, Values& v)
{
    const Net::Node& node = nodes[size_t(step.id)];
    auto in = [&](int k) -> const Tensor& { return *v.value[size_t(node.inputs[size_t(k)])]; };
    Tensor& out = v.owned[size_t(step.id)];
    switch (step.kind) {
    case Step::Kind::conv:
        v.fresh(step, node);
        if (fast)
            state.convs.at(step.id).run(state.engine, state.stream, in(0), out);
        else
            reference::conv(in(0), weights[size_t(step.id)], biases[size_t(step.id)], node.kernel,
                            node.activation, out);
        break;
    case Step::Kind::conv_sum: {
        const Tensor& residual = *v.value[size_t(step.other)];
        if (step.in_place) {
            out = std::move(v.owned[size_t(step.other)]);  // nobody else reads it any more
            v.home[size_t(step.id)] = v.home[size_t(step.other)];
            v.home[size_t(step.other)] = -1;
        } else {
            v.fresh(step, node);
            out.height = residual.height;
            out.width = residual.width;
            out.channels = residual.channels;
            out.data.assign(residual.data.begin(), residual.data.begin() + residual.size());
        }
        state.convs.at(step.id).run_accumulate(state.engine, state.stream, in(0), out,
                                               step.after_sum);
        break;
    }
    case Step::Kind::take:
        out = std::move(v.owned[size_t(step.other)]);  // summed, activated by the conv
        v.home[size_t(step.id)] = v.home[size_t(step.other)];
        v.home[size_t(step.other)] = -1;
        break;
    case Step::Kind::add:
        v.fresh(step, node);
        fast ? ops::add(in(0), in(1), node.activation, out)
             : reference::add(in(0), in(1), node.activation, out);
        break;
    case Step::Kind::max_pool2:
        v.fresh(step, node);
        fast ? ops::max_pool2(in(0), out) : reference::max_pool2(in(0), out);
        break;
    case Step::Kind::upsample2:
        v.fresh(step, node);
        fast ? ops::upsample2(in(0), out) : reference::upsample2(in(0), out);
        break;
    case Step::Kind::concat: {
        std::vector<const Tensor*> parts;
        for (int k = 0; k < int(node.inputs.size()); ++k)
            parts.push_back(step.upsampled[size_t(k)]  // the fused upsample's input
                                ? v.value[size_t(nodes[size_t(node.inputs[size_t(k)])].inputs[0])]
                                : &in(k));
        v.fresh(step, node);
        fast ? ops::concat(parts, step.upsampled, out) : reference::concat(parts, out);
        break;
    }
    case Step::Kind::slice:
        v.fresh(step, node);
        fast ? ops::slice(in(0), node.first_channel, node.channels, out)
             : reference::slice(in(0), node.first_channel, node.channels, out);
        break;
    case Step::Kind::upconv: {
        const Net::Node& joined = nodes[size_t(node.inputs[0])];  // concat(upsample2(x), skip)
        const Tensor& x = *v.value[size_t(nodes[size_t(joined.inputs[0])].inputs[0])];
        const Tensor& skip = *v.value[size_t(joined.inputs[1])];
        Tensor phase = v.scratch(step, node);
        v.fresh(step, node);
        state.upconvs.at(step.id).run(state.engine, state.stream, x, skip, phase, out);
        v.release_scratch(step, phase);
        break;
    }
    case Step::Kind::view: v.value[size_t(step.id)] = v.value[size_t(step.other)]; return;
    case Step::Kind::apply_kernel:
        v.fresh(step, node);
        if (fast)
            ops::apply_kernel(*v.value[size_t(step.other)], step.first_channel, in(1), node.kernel,
                              out);
        else
            reference::apply_kernel(in(0), in(1), node.kernel, out);
        break;
    case Step::Kind::apply_kernel_head: {
        v.fresh(step, node);
        const int head = step.other;
        const Tensor& features = *v.value[size_t(nodes[size_t(head)].inputs[0])];
        ops::apply_kernel_head(
            features, weights[size_t(head)].data() + size_t(step.first_channel) * features.channels,
            biases[size_t(head)].data() + step.first_channel, in(1), node.kernel, out);
        break;
    }
    }
    v.value[size_t(step.id)] = &out;
}

}  // namespace

void Net::make_state()
{
    state_ = std::make_unique<NetState>();
    for (int b = 0; b < 2; ++b) {
        state_->plan[b] = plan_steps(nodes_, output_ids_, b == 0);
        state_->storage[b] = plan_storage(state_->plan[b], nodes_, output_ids_);
        state_->slots[b].resize(state_->storage[b].slot_floats.size());
    }
    // oneDNN layers for the convs the fast plan runs as convs; a conv it fuses into a kernel
    // head or runs as an upconv reads its weights there instead (the reference plan reads
    // the weights as they are).
    for (const Step& step : state_->plan[0]) {
        const Node& conv = nodes_[size_t(step.id)];
        if (step.kind == Step::Kind::conv || step.kind == Step::Kind::conv_sum)
            state_->convs.emplace(std::piecewise_construct, std::forward_as_tuple(step.id),
                                  std::forward_as_tuple(nodes_[size_t(conv.inputs[0])].channels,
                                                        conv.channels, conv.kernel, conv.activation,
                                                        weights_[size_t(step.id)],
                                                        biases_[size_t(step.id)]));
        else if (step.kind == Step::Kind::upconv) {
            const Node& joined = nodes_[size_t(conv.inputs[0])];
            state_->upconvs.emplace(std::piecewise_construct, std::forward_as_tuple(step.id),
                                    std::forward_as_tuple(nodes_[size_t(joined.inputs[0])].channels,
                                                          nodes_[size_t(joined.inputs[1])].channels,
                                                          conv.channels, conv.activation,
                                                          weights_[size_t(step.id)],
                                                          biases_[size_t(step.id)]));
        }
    }
}

void Net::give_buffers(Net& other)
{
    if (!state_ || &other == this || !other.loaded_)
        return;
    if (!other.state_)
        other.make_state();
    for (auto& slots : state_->slots)
        for (std::vector<float>& buffer : slots)
            if (buffer.capacity() > 0)
                other.state_->spare.push_back(std::move(buffer));
    for (std::vector<float>& buffer : state_->spare)
        other.state_->spare.push_back(std::move(buffer));
    state_->spare.clear();
}

bool Net::check_inputs(const std::vector<Tensor>& inputs, std::string& error) const
{
    const std::string prefix = "network '" + name_ + "': ";
    if (!build_error_.empty()) {
        error = build_error_;
        return false;
    }
    if (!loaded_) {
        error = prefix + "run before load() of its weights";
        return false;
    }
    if (inputs.size() != input_ids_.size() || output_ids_.empty()) {
        error = prefix + "expects " + std::to_string(input_ids_.size()) + " inputs, got "
                + std::to_string(inputs.size())
                + (output_ids_.empty() ? " (and has no output)" : "");
        return false;
    }
    const int alignment = this->alignment();
    for (size_t i = 0; i < inputs.size(); ++i) {
        const Node& node = nodes_[input_ids_[i]];
        const Tensor& t = inputs[i];
        if (t.channels != node.channels || t.height != inputs[0].height
            || t.width != inputs[0].width || t.data.size() < t.size()) {
            error = prefix + "input '" + node.name + "' is " + std::to_string(t.width) + "x"
                    + std::to_string(t.height) + "x" + std::to_string(t.channels) + ", expected "
                    + std::to_string(node.channels) + " channels and the size of the first input";
            return false;
        }
        if (t.height % alignment || t.width % alignment || t.height == 0 || t.width == 0) {
            error = prefix + "input '" + node.name + "' is " + std::to_string(t.width) + "x"
                    + std::to_string(t.height) + "; sizes must be multiples of "
                    + std::to_string(alignment) + " (run_tiled extends any size)";
            return false;
        }
    }
    return true;
}

bool Net::run(const std::vector<Tensor>& inputs, std::vector<Tensor>& outputs, std::string& error,
              Backend backend)
{
    if (!check_inputs(inputs, error))
        return false;
    if (!state_)
        make_state();
    const bool fast = backend == Backend::onednn;
    const int b = fast ? 0 : 1;
    // Storage comes from the plan's slots (net_plan.h), filled by the values of earlier runs
    // (whose outputs the caller hands back in `outputs`): a tiled run allocates for its first
    // tile only.
    Values v { std::vector<Tensor>(nodes_.size()),
               std::vector<const Tensor*>(nodes_.size()),
               std::vector<int>(nodes_.size(), -1),
               state_->slots[b],
               state_->storage[b],
               state_->spare,
               inputs[0].height,
               inputs[0].width };
    for (size_t i = 0; i < inputs.size(); ++i)
        v.value[size_t(input_ids_[i])] = &inputs[i];
    const std::vector<int>& output_slot = state_->storage[b].output_slot;
    for (size_t i = 0; i < outputs.size(); ++i) {
        const int slot = i < output_slot.size() ? output_slot[i] : -1;
        std::vector<float>& data = outputs[i].data;
        if (slot >= 0 && v.slots[size_t(slot)].capacity() == 0)
            v.slots[size_t(slot)] = std::move(data);
        else if (data.capacity() > 0)
            v.spare.push_back(std::move(data));
    }
    outputs.clear();
    for (const Step& step : state_->plan[b]) {
        run_step(step, nodes_, *state_, weights_, biases_, fast, v);
        for (int k : step.free_after)
            if (v.value[size_t(k)] == &v.owned[size_t(k)])
                v.release(k);
    }
    for (size_t i = 0; i < output_ids_.size(); ++i) {
        const int id = output_ids_[i];
        const bool output_again =
            std::find(output_ids_.begin() + i + 1, output_ids_.end(), id) != output_ids_.end();
        if (v.value[size_t(id)] == &v.owned[size_t(id)] && !output_again)
            outputs.push_back(std::move(v.owned[size_t(id)]));
        else
            outputs.push_back(*v.value[size_t(id)]);        // an input, or a value output twice
        outputs.back().data.resize(outputs.back().size());  // exact, as the caller expects
    }
    for (size_t id = 0; id < v.owned.size(); ++id)  // values nobody read
        v.release(int(id));
    return true;
}

}  // namespace nn
}  // namespace mcdn
