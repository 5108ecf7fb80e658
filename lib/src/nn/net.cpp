// Net: the builder (shape, scale and receptive field of every value, checked as the
// network is written), load() (parameters by name, shapes checked) and run() (the ops in
// order, each value freed after its last reader).
#include <algorithm>
#include <cmath>

#include "nn/onednn_conv.h"
#include "nn/ops.h"

namespace mcdn {
namespace nn {

Net::Net(std::string name) : name_(std::move(name)) {}
Net::~Net() = default;
Net::Net(Net&&) noexcept = default;
Net& Net::operator=(Net&&) noexcept = default;

void Net::fail(const std::string& message)
{
    if (build_error_.empty())  // the first mistake explains the rest
        build_error_ = "network '" + name_ + "': " + message;
}

bool Net::check(Value x, const char* op)
{
    if (x.id >= 0 && x.id < int(nodes_.size()))
        return true;
    fail(std::string(op) + " reads a value that is not from this network");
    return false;
}

Value Net::add_node(Node node)
{
    loaded_ = false;  // the parameters no longer match the graph
    nodes_.push_back(std::move(node));
    return Value { int(nodes_.size()) - 1 };
}

int Net::channels(Value x) const
{
    return x.id >= 0 && x.id < int(nodes_.size()) ? nodes_[x.id].channels : 0;
}

Value Net::input(const std::string& name, int channels)
{
    if (channels <= 0)
        fail("input '" + name + "' needs at least one channel");
    Node node { Op::input, name, {}, channels };
    input_ids_.push_back(int(nodes_.size()));
    return add_node(node);
}

Value Net::conv(Value x, const std::string& param, int out_channels, int kernel,
                Activation activation)
{
    if (!check(x, "conv"))
        return x;
    if (kernel <= 0 || kernel % 2 == 0 || out_channels <= 0)
        fail("conv '" + param + "' needs an odd kernel size and output channels (same padding)");
    const Node& in = nodes_[x.id];
    Node node { Op::conv, param, { x.id }, out_channels, kernel };
    node.activation = activation;
    node.scale = in.scale;
    node.radius = in.radius + (kernel / 2) * in.scale;
    return add_node(node);
}

Value Net::add(Value a, Value b, Activation activation)
{
    if (!check(a, "add") || !check(b, "add"))
        return a;
    const Node &na = nodes_[a.id], &nb = nodes_[b.id];
    if (na.channels != nb.channels || na.scale != nb.scale)
        fail("add of values with " + std::to_string(na.channels) + " and "
             + std::to_string(nb.channels) + " channels at scales 1/" + std::to_string(na.scale)
             + " and 1/" + std::to_string(nb.scale) + " (they must match)");
    Node node { Op::add, "", { a.id, b.id }, na.channels };
    node.activation = activation;
    node.scale = na.scale;
    node.radius = std::max(na.radius, nb.radius);
    return add_node(node);
}

Value Net::max_pool2(Value x)
{
    if (!check(x, "max_pool2"))
        return x;
    const Node& in = nodes_[x.id];
    Node node { Op::max_pool2, "", { x.id }, in.channels };
    node.scale = in.scale * 2;
    node.radius = in.radius + in.scale;  // the 2×2 window reaches one input pixel further
    return add_node(node);
}

Value Net::upsample2(Value x)
{
    if (!check(x, "upsample2"))
        return x;
    const Node& in = nodes_[x.id];
    if (in.scale < 2)
        fail("upsample2 above the input resolution (not supported by tiling)");
    Node node { Op::upsample2, "", { x.id }, in.channels };
    node.scale = std::max(in.scale / 2, 1);
    node.radius = in.radius + node.scale;  // a pixel copies a neighbour up to 1 step away
    return add_node(node);
}

Value Net::concat(const std::vector<Value>& values)
{
    if (values.empty()) {
        fail("concat of nothing");
        return Value {};
    }
    Node node { Op::concat, "", {}, 0 };
    for (Value v : values) {
        if (!check(v, "concat"))
            return v;
        const Node& in = nodes_[v.id];
        if (in.scale != nodes_[values[0].id].scale)
            fail("concat of values at different scales (1/" + std::to_string(in.scale)
                 + " and 1/" + std::to_string(nodes_[values[0].id].scale) + ")");
        node.inputs.push_back(v.id);
        node.channels += in.channels;
        node.scale = in.scale;
        node.radius = std::max(node.radius, in.radius);
    }
    return add_node(node);
}

Value Net::slice(Value x, int first, int count)
{
    if (!check(x, "slice"))
        return x;
    const Node& in = nodes_[x.id];
    if (first < 0 || count <= 0 || first + count > in.channels)
        fail("slice [" + std::to_string(first) + ", " + std::to_string(first + count)
             + ") of a value with " + std::to_string(in.channels) + " channels");
    Node node { Op::slice, "", { x.id }, count };
    node.first_channel = first;
    node.scale = in.scale;
    node.radius = in.radius;
    return add_node(node);
}

Value Net::apply_kernel(Value logits, Value image, int kernel)
{
    if (!check(logits, "apply_kernel") || !check(image, "apply_kernel"))
        return image;
    const Node &nl = nodes_[logits.id], &ni = nodes_[image.id];
    if (kernel <= 0 || kernel % 2 == 0 || nl.channels != kernel * kernel)
        fail("apply_kernel of size " + std::to_string(kernel) + " needs an odd size and "
             + std::to_string(kernel * kernel) + " logit channels, got "
             + std::to_string(nl.channels));
    if (nl.scale != ni.scale)
        fail("apply_kernel with logits and image at different scales");
    Node node { Op::apply_kernel, "", { logits.id, image.id }, ni.channels, kernel };
    node.scale = ni.scale;
    node.radius = std::max(nl.radius, ni.radius + (kernel / 2) * ni.scale);
    return add_node(node);
}

void Net::output(const std::string& name, Value x)
{
    if (!check(x, "output"))
        return;
    output_ids_.push_back(x.id);
    output_names_.push_back(name);
}

int Net::alignment() const
{
    int alignment = 1;
    for (const Node& node : nodes_)
        alignment = std::max(alignment, node.scale);
    return alignment;
}

int Net::receptive_radius() const
{
    double radius = 0;
    for (int id : output_ids_)
        radius = std::max(radius, nodes_[id].radius);
    return int(std::ceil(radius));
}

std::string Net::expected_parameters() const
{
    std::string list;
    for (const Node& node : nodes_)
        if (node.op == Op::conv) {
            const int in_channels = nodes_[node.inputs[0]].channels;
            list += node.name + ".weight "
                    + shape_string({ node.channels, in_channels, node.kernel, node.kernel }) + "\n"
                    + node.name + ".bias " + shape_string({ node.channels }) + "\n";
        }
    return list;
}

// ---------------------------------------------------------------------------------------
// load

namespace {

/// The tensor `name` of `weights` with exactly `shape`, or nullptr and a one-line error.
const NamedTensor* find_tensor(const Weights& weights, const std::string& net_name,
                               const std::string& name, const std::vector<int>& shape,
                               std::string& error)
{
    const std::string file = weights.path.empty() ? "weights" : weights.path;
    const NamedTensor* tensor = weights.find(name);
    if (!tensor) {
        error = file + ": tensor '" + name + "' is missing, the network '" + net_name
                + "' expects " + shape_string(shape) + " (the file has "
                + std::to_string(weights.tensors.size()) + " tensors: is it for this network?)";
        return nullptr;
    }
    if (tensor->shape != shape) {
        error = file + ": tensor '" + name + "' has shape " + shape_string(tensor->shape)
                + ", the network '" + net_name + "' expects " + shape_string(shape);
        return nullptr;
    }
    return tensor;
}

}  // namespace

bool Net::load(const Weights& weights, std::string& error)
{
    loaded_ = false;
    state_.reset();
    if (!build_error_.empty()) {
        error = build_error_;
        return false;
    }
    weights_.assign(nodes_.size(), {});
    biases_.assign(nodes_.size(), {});
    std::vector<std::string> used;
    for (size_t id = 0; id < nodes_.size(); ++id) {
        const Node& node = nodes_[id];
        if (node.op != Op::conv)
            continue;
        const int in_channels = nodes_[node.inputs[0]].channels;
        const std::string weight_name = node.name + ".weight", bias_name = node.name + ".bias";
        const NamedTensor* w = find_tensor(weights, name_, weight_name,
                                           { node.channels, in_channels, node.kernel, node.kernel },
                                           error);
        const NamedTensor* b = w ? find_tensor(weights, name_, bias_name, { node.channels }, error)
                                 : nullptr;
        if (!b)
            return false;
        weights_[id] = w->values;
        biases_[id] = b->values;
        used.push_back(weight_name);
        used.push_back(bias_name);
    }
    // Like torch's strict load_state_dict: a tensor nobody reads means another architecture.
    for (const NamedTensor& t : weights.tensors)
        if (std::find(used.begin(), used.end(), t.name) == used.end()) {
            error = (weights.path.empty() ? "weights" : weights.path) + ": tensor '" + t.name
                    + "' " + shape_string(t.shape) + " is not used by the network '" + name_
                    + "' (is the file for another architecture?)";
            return false;
        }
    loaded_ = true;
    return true;
}

// ---------------------------------------------------------------------------------------
// run

namespace {

/// Whether a node in [first, last) reads value v (then v cannot be overwritten in place).
bool reads(const std::vector<Net::Node>& nodes, int v, int first, int last)
{
    for (int id = first; id < last; ++id)
        if (std::find(nodes[id].inputs.begin(), nodes[id].inputs.end(), v) != nodes[id].inputs.end())
            return true;
    return false;
}

/// When each value can be freed, which convs carry the add that follows them, and which
/// slices are only views.
struct Schedule {
    /// The last node reading each value (node count for outputs): each value is freed after
    /// it, so memory holds the widest few layers, not all of them.
    std::vector<int> last_reader;
    /// The values whose storage is free once node id has run (the inverse of last_reader).
    std::vector<std::vector<int>> free_after;
    /// Residual fusion: a conv whose only reader is add(s, conv), with s computed earlier,
    /// accumulates into a copy of s (or into s itself, when nothing else reads it) through
    /// oneDNN's sum post-op; the add then hands the result on. fused_add[conv] = the add,
    /// summed_conv[add] = the conv, residual_of[conv] = s.
    std::vector<int> fused_add, summed_conv, residual_of;
    /// The fused conv may take s's storage: s is computed (not an input or a view) and the
    /// add is its last reader, with no node in between reading it.
    std::vector<char> accumulate_in_place;
    /// A slice read only as the logits of apply_kernel is never copied out: apply_kernel
    /// reads its channels in place. view_of[slice] = the sliced value, else -1.
    std::vector<int> view_of;
    /// The kernel head: a 1×1 conv without activation read only through such slices is
    /// never run; each apply_kernel computes its logits from the conv's input and rows of
    /// its weights (ops::apply_kernel_head). fused_head[conv] = 1.
    std::vector<char> fused_head;
};

Schedule make_schedule(const std::vector<Net::Node>& nodes, const std::vector<int>& outputs,
                       bool fuse)
{
    const int count = int(nodes.size());
    Schedule schedule;
    schedule.last_reader.assign(count, -1);
    schedule.free_after.resize(count);
    schedule.fused_add.assign(count, -1);
    schedule.summed_conv.assign(count, -1);
    schedule.residual_of.assign(count, -1);
    schedule.accumulate_in_place.assign(count, 0);
    schedule.view_of.assign(count, -1);
    schedule.fused_head.assign(count, 0);
    std::vector<int> readers(count, 0), kernel_readers(count, 0);
    for (int id = 0; id < count; ++id)
        for (size_t k = 0; k < nodes[id].inputs.size(); ++k) {
            const int in = nodes[id].inputs[k];
            schedule.last_reader[in] = id;
            ++readers[in];
            if (nodes[id].op == Net::Op::apply_kernel && k == 0)
                ++kernel_readers[in];
        }
    for (int id : outputs) {
        schedule.last_reader[id] = count;  // kept to the end
        ++readers[id];
    }
    for (int id = 0; fuse && id < count; ++id) {
        if (nodes[id].op == Net::Op::slice && readers[id] > 0 && readers[id] == kernel_readers[id]) {
            const int source = nodes[id].inputs[0];
            schedule.view_of[id] = source;
            schedule.last_reader[source] = std::max(schedule.last_reader[source],
                                                    schedule.last_reader[id]);
        }
        if (nodes[id].op != Net::Op::add)
            continue;
        const int a = nodes[id].inputs[0], b = nodes[id].inputs[1];
        const int conv = nodes[b].op == Net::Op::conv && a < b ? b : a;
        const int residual = conv == b ? a : b;
        if (nodes[conv].op == Net::Op::conv && readers[conv] == 1 && residual < conv) {
            schedule.fused_add[conv] = id;
            schedule.summed_conv[id] = conv;
            schedule.residual_of[conv] = residual;
        }
    }
    std::vector<int> view_readers(count, 0);
    for (int id = 0; id < count; ++id)
        if (schedule.view_of[id] >= 0)
            ++view_readers[schedule.view_of[id]];
    for (int id = 0; fuse && id < count; ++id) {
        const Net::Node& node = nodes[id];
        if (node.op == Net::Op::conv && node.kernel == 1 && node.activation == Activation::none
            && readers[id] > 0 && readers[id] == view_readers[id]) {
            schedule.fused_head[id] = 1;
            const int features = node.inputs[0];  // read by every apply_kernel instead
            schedule.last_reader[features] = std::max(schedule.last_reader[features],
                                                      schedule.last_reader[id]);
        }
    }
    for (int conv = 0; conv < count; ++conv) {
        const int add = schedule.fused_add[conv], residual = schedule.residual_of[conv];
        if (add >= 0)
            schedule.accumulate_in_place[conv] =
                nodes[residual].op != Net::Op::input && schedule.view_of[residual] < 0
                && schedule.last_reader[residual] == add && !reads(nodes, residual, conv, add);
    }
    for (int id = 0; id < count; ++id)
        if (schedule.last_reader[id] >= 0 && schedule.last_reader[id] < count
            && !(schedule.fused_head[id]))
            schedule.free_after[schedule.last_reader[id]].push_back(id);
    return schedule;
}

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

void give_back(std::vector<std::vector<float>>& spare, Tensor& t)
{
    if (t.data.capacity() > 0)
        spare.push_back(std::move(t.data));
    t = Tensor();
}

}  // namespace

void Net::make_state()
{
    state_ = std::make_unique<NetState>();
    for (size_t id = 0; id < nodes_.size(); ++id)
        if (nodes_[id].op == Op::conv)
            state_->convs.emplace(
                std::piecewise_construct, std::forward_as_tuple(int(id)),
                std::forward_as_tuple(nodes_[nodes_[id].inputs[0]].channels, nodes_[id].channels,
                                      nodes_[id].kernel, nodes_[id].activation, weights_[id],
                                      biases_[id]));
}

void Net::give_buffers(Net& other)
{
    if (!state_ || &other == this || !other.loaded_)
        return;
    if (!other.state_)
        other.make_state();
    for (std::vector<float>& buffer : state_->spare)
        other.state_->spare.push_back(std::move(buffer));
    state_->spare.clear();
}

bool Net::run(const std::vector<Tensor>& inputs, std::vector<Tensor>& outputs, std::string& error,
              Backend backend)
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
                + std::to_string(inputs.size()) + (output_ids_.empty() ? " (and has no output)" : "");
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
    if (!state_)
        make_state();

    const int count = int(nodes_.size());
    const bool fast = backend == Backend::onednn;
    const Schedule schedule = make_schedule(nodes_, output_ids_, fast);
    std::vector<Tensor> owned(count);
    std::vector<const Tensor*> value(count, nullptr);
    for (size_t i = 0; i < inputs.size(); ++i)
        value[input_ids_[i]] = &inputs[i];
    // Storage comes from values freed earlier, this run or the last (whose outputs the
    // caller hands back in `outputs`): a tiled run allocates for its first tile only.
    std::vector<std::vector<float>>& spare = state_->spare;
    for (Tensor& t : outputs)
        give_back(spare, t);
    outputs.clear();
    const int height = inputs[0].height, width = inputs[0].width;

    for (int id = 0; id < count; ++id) {
        const Node& node = nodes_[id];
        auto in = [&](int k) -> const Tensor& { return *value[node.inputs[k]]; };
        Tensor& out = owned[id];
        auto fresh = [&] {  // out gets storage for its values, reshaped by the op
            out.data = take_storage(spare, size_t(height / node.scale) * (width / node.scale)
                                               * node.channels);
        };
        switch (node.op) {
        case Op::input: continue;
        case Op::conv:
            if (schedule.fused_head[id])
                continue;  // computed inside the apply_kernels that read it
            if (schedule.fused_add[id] >= 0) {
                const Node& add = nodes_[schedule.fused_add[id]];
                const int residual = schedule.residual_of[id];
                if (schedule.accumulate_in_place[id])
                    out = std::move(owned[residual]);  // nobody else reads it any more
                else {
                    fresh();
                    out.height = value[residual]->height;
                    out.width = value[residual]->width;
                    out.channels = value[residual]->channels;
                    out.data.assign(value[residual]->data.begin(),
                                    value[residual]->data.begin() + value[residual]->size());
                }
                state_->convs.at(id).run_accumulate(state_->engine, state_->stream, in(0), out,
                                                    add.activation);
            } else if (fast) {
                fresh();
                state_->convs.at(id).run(state_->engine, state_->stream, in(0), out);
            } else
                reference::conv(in(0), weights_[id], biases_[id], node.kernel, node.activation, out);
            break;
        case Op::add:
            if (schedule.summed_conv[id] >= 0) {
                out = std::move(owned[schedule.summed_conv[id]]);  // summed, activated by the conv
                break;
            }
            fresh();
            fast ? ops::add(in(0), in(1), node.activation, out)
                 : reference::add(in(0), in(1), node.activation, out);
            break;
        case Op::max_pool2:
            fresh();
            fast ? ops::max_pool2(in(0), out) : reference::max_pool2(in(0), out);
            break;
        case Op::upsample2:
            fresh();
            fast ? ops::upsample2(in(0), out) : reference::upsample2(in(0), out);
            break;
        case Op::concat: {
            std::vector<const Tensor*> parts;
            for (int k = 0; k < int(node.inputs.size()); ++k)
                parts.push_back(&in(k));
            fresh();
            fast ? ops::concat(parts, out) : reference::concat(parts, out);
            break;
        }
        case Op::slice:
            if (schedule.view_of[id] >= 0) {
                value[id] = value[node.inputs[0]];  // apply_kernel reads the channels where they are
                continue;
            }
            fresh();
            fast ? ops::slice(in(0), node.first_channel, node.channels, out)
                 : reference::slice(in(0), node.first_channel, node.channels, out);
            break;
        case Op::apply_kernel:
            fresh();
            if (!fast) {
                reference::apply_kernel(in(0), in(1), node.kernel, out);
                break;
            }
            {
                const int logits = node.inputs[0], sliced = schedule.view_of[logits];
                const int first = sliced >= 0 ? nodes_[logits].first_channel : 0;
                if (sliced >= 0 && schedule.fused_head[sliced]) {
                    const Tensor& features = *value[nodes_[sliced].inputs[0]];
                    ops::apply_kernel_head(features,
                                           weights_[sliced].data() + size_t(first) * features.channels,
                                           biases_[sliced].data() + first, in(1), node.kernel, out);
                } else
                    ops::apply_kernel(in(0), first, in(1), node.kernel, out);
            }
            break;
        }
        value[id] = &out;
        for (int k : schedule.free_after[id])
            if (value[k] == &owned[k])
                give_back(spare, owned[k]);
    }

    for (size_t i = 0; i < output_ids_.size(); ++i) {
        const int id = output_ids_[i];
        const bool output_again = std::find(output_ids_.begin() + i + 1, output_ids_.end(), id)
                                  != output_ids_.end();
        if (value[id] == &owned[id] && !output_again)
            outputs.push_back(std::move(owned[id]));
        else
            outputs.push_back(*value[id]);  // an input, or a value output twice
        outputs.back().data.resize(outputs.back().size());  // exact, as the caller expects
    }
    for (Tensor& t : owned)  // values nobody read
        give_back(spare, t);
    return true;
}

}  // namespace nn
}  // namespace mcdn
