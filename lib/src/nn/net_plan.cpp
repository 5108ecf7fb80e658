// Net's plan (net_plan.h): which values are freed after which node, and the fusions of the
// oneDNN backend, decided once per network and backend.
#include "nn/net_plan.h"

#include <algorithm>

namespace mcdn {
namespace nn {

namespace {

/// Whether a node in [first, last) reads value v (then v cannot be overwritten in place).
bool reads(const std::vector<Net::Node>& nodes, int v, int first, int last)
{
    for (int id = first; id < last; ++id)
        if (std::find(nodes[id].inputs.begin(), nodes[id].inputs.end(), v)
            != nodes[id].inputs.end())
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
    /// An upsample2 read only by a concat (a UNet's decoder) is never run: the concat reads
    /// its input at half resolution. upsample_into[upsample] = the concat, else -1.
    std::vector<int> upsample_into;
    /// A 3×3 conv (with no add fused) whose input is such a concat of two, read by it alone,
    /// is an upconv (UpConvLayer): it reads the upsample's input and the skip, and the concat
    /// is never made. upconv[conv] = 1, concat_into[concat] = the conv, else -1.
    std::vector<char> upconv;
    std::vector<int> concat_into;
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
    schedule.upsample_into.assign(count, -1);
    schedule.upconv.assign(count, 0);
    schedule.concat_into.assign(count, -1);
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
        if (nodes[id].op == Net::Op::slice && readers[id] > 0
            && readers[id] == kernel_readers[id]) {
            const int source = nodes[id].inputs[0];
            schedule.view_of[id] = source;
            schedule.last_reader[source] =
                std::max(schedule.last_reader[source], schedule.last_reader[id]);
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
    for (int id = 0; fuse && id < count; ++id)
        if (nodes[id].op == Net::Op::upsample2 && readers[id] == 1
            && nodes[schedule.last_reader[id]].op == Net::Op::concat
            && nodes[schedule.last_reader[id]].inputs[0] == id) {
            // The first part sets the concat's size: only it may be read at half resolution.
            schedule.upsample_into[id] = schedule.last_reader[id];
            const int source = nodes[id].inputs[0];
            schedule.last_reader[source] =
                std::max(schedule.last_reader[source], schedule.upsample_into[id]);
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
            schedule.last_reader[features] =
                std::max(schedule.last_reader[features], schedule.last_reader[id]);
        }
    }
    for (int id = 0; fuse && id < count; ++id) {
        const Net::Node& node = nodes[id];
        if (node.op != Net::Op::conv || node.kernel != 3 || schedule.fused_add[id] >= 0
            || schedule.fused_head[id])
            continue;
        const int joined = node.inputs[0];
        if (nodes[joined].op != Net::Op::concat || readers[joined] != 1
            || nodes[joined].inputs.size() != 2
            || schedule.upsample_into[nodes[joined].inputs[0]] != joined)
            continue;
        schedule.upconv[id] = 1;
        schedule.concat_into[joined] = id;
        for (int read : { nodes[nodes[joined].inputs[0]].inputs[0], nodes[joined].inputs[1] })
            schedule.last_reader[read] = std::max(schedule.last_reader[read], id);
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
            && !schedule.fused_head[id] && schedule.upsample_into[id] < 0
            && schedule.concat_into[id] < 0)
            schedule.free_after[schedule.last_reader[id]].push_back(id);
    return schedule;
}

}  // namespace

std::vector<Step> plan_steps(const std::vector<Net::Node>& nodes, const std::vector<int>& outputs,
                             bool fuse)
{
    const Schedule schedule = make_schedule(nodes, outputs, fuse);
    std::vector<Step> steps;
    std::vector<int> pending_frees;  // of nodes that need no step (none, as planned)
    for (int id = 0; id < int(nodes.size()); ++id) {
        const Net::Node& node = nodes[id];
        Step step;
        step.id = id;
        switch (node.op) {
        case Net::Op::input: break;
        case Net::Op::conv:
            if (schedule.fused_head[id])
                break;  // computed inside the apply_kernels that read it
            if (schedule.upconv[id])
                step.kind = Step::Kind::upconv;
            else if (schedule.fused_add[id] >= 0) {
                step.kind = Step::Kind::conv_sum;
                step.other = schedule.residual_of[id];
                step.in_place = schedule.accumulate_in_place[id];
                step.after_sum = nodes[schedule.fused_add[id]].activation;
            } else
                step.kind = Step::Kind::conv;
            steps.push_back(step);
            break;
        case Net::Op::add:
            step.kind = schedule.summed_conv[id] >= 0 ? Step::Kind::take : Step::Kind::add;
            step.other = schedule.summed_conv[id];
            steps.push_back(step);
            break;
        case Net::Op::max_pool2:
            step.kind = Step::Kind::max_pool2;
            steps.push_back(step);
            break;
        case Net::Op::upsample2:
            if (schedule.upsample_into[id] >= 0)
                break;  // read by its concat at half resolution
            step.kind = Step::Kind::upsample2;
            steps.push_back(step);
            break;
        case Net::Op::concat:
            if (schedule.concat_into[id] >= 0)
                break;  // read by its upconv as its two parts
            step.kind = Step::Kind::concat;
            for (int in : node.inputs)
                step.upsampled.push_back(schedule.upsample_into[in] == id);
            steps.push_back(step);
            break;
        case Net::Op::slice:
            step.kind = schedule.view_of[id] >= 0 ? Step::Kind::view : Step::Kind::slice;
            step.other = schedule.view_of[id];
            steps.push_back(step);
            break;
        case Net::Op::apply_kernel: {
            const int logits = node.inputs[0], sliced = fuse ? schedule.view_of[logits] : -1;
            step.kind = Step::Kind::apply_kernel;
            step.other = logits;
            if (sliced >= 0) {
                step.first_channel = nodes[logits].first_channel;
                step.other = sliced;
                if (schedule.fused_head[sliced])
                    step.kind = Step::Kind::apply_kernel_head;
            }
            steps.push_back(step);
            break;
        }
        }
        // Frees after a node without a step (an input, a fused head) go with the next step.
        pending_frees.insert(pending_frees.end(), schedule.free_after[id].begin(),
                             schedule.free_after[id].end());
        if (!steps.empty() && steps.back().id == id) {
            steps.back().free_after = std::move(pending_frees);
            pending_frees.clear();
        }
    }
    return steps;
}

bool computes_into_storage(const Step& step)
{
    switch (step.kind) {
    case Step::Kind::take:
    case Step::Kind::view: return false;
    case Step::Kind::conv_sum: return !step.in_place;
    default: return true;
    }
}

StoragePlan plan_storage(std::vector<Step>& steps, const std::vector<Net::Node>& nodes,
                         const std::vector<int>& outputs)
{
    StoragePlan plan;
    std::vector<int> home(nodes.size(), -1);  // the slot each value's storage is in
    std::vector<char> busy;
    auto release = [&](int id) {
        if (home[size_t(id)] >= 0)
            busy[size_t(home[size_t(id)])] = 0;
        home[size_t(id)] = -1;
    };
    // The smallest free slot that holds `floats` a pixel, else the largest free one (grown
    // to it), else a new one; busy from now on.
    auto take_slot = [&](double floats) {
        int fits = -1, largest = -1;
        for (int k = 0; k < int(busy.size()); ++k) {
            if (busy[size_t(k)])
                continue;
            const double size = plan.slot_floats[size_t(k)];
            if (size >= floats && (fits < 0 || size < plan.slot_floats[size_t(fits)]))
                fits = k;
            if (largest < 0 || size > plan.slot_floats[size_t(largest)])
                largest = k;
        }
        int slot = fits >= 0 ? fits : largest;
        if (slot < 0) {
            slot = int(busy.size());
            busy.push_back(0);
            plan.slot_floats.push_back(0);
        }
        plan.slot_floats[size_t(slot)] = std::max(plan.slot_floats[size_t(slot)], floats);
        busy[size_t(slot)] = 1;
        return slot;
    };
    for (Step& step : steps) {
        if (step.kind == Step::Kind::take || (step.kind == Step::Kind::conv_sum && step.in_place)) {
            home[size_t(step.id)] = home[size_t(step.other)];  // handed on with its storage
            home[size_t(step.other)] = -1;
        } else if (computes_into_storage(step)) {
            const Net::Node& node = nodes[size_t(step.id)];
            const double floats = double(node.channels) / (double(node.scale) * node.scale);
            // An upconv's phase: its channels at half the output's resolution; busy while
            // the output's slot is chosen, free again after the step.
            if (step.kind == Step::Kind::upconv)
                step.scratch_slot = take_slot(floats / 4);
            step.slot = take_slot(floats);
            home[size_t(step.id)] = step.slot;
            if (step.scratch_slot >= 0)
                busy[size_t(step.scratch_slot)] = 0;
        }
        for (int k : step.free_after)
            release(k);
    }
    for (size_t i = 0; i < outputs.size(); ++i) {
        const int id = outputs[i];
        const bool again =
            std::find(outputs.begin() + long(i) + 1, outputs.end(), id) != outputs.end();
        plan.output_slot.push_back(again ? -1 : home[size_t(id)]);
    }
    return plan;
}

}  // namespace nn
}  // namespace mcdn
