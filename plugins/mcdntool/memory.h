// Whether a frame's chain fits in the machine's memory, checked before its first stage.
#pragma once

#include <string>
#include <vector>

#include "command.h"

namespace mcdntool {

/// A lower bound of the peak memory of running `commands` on a frame of `pixels` pixels
/// and `channels` float channels (of the merged input: those read), in bytes. Stages keep
/// frame-sized buffers (the merged input, each result, SURE's noisy copy) and the
/// CNN per-thread network buffers; the factors are those of whole mcdntool runs on Blender
/// files (bench/), rounded down so that a run which fits is never refused.
/// A command line that streams (streamed_chain_start) keeps the merged input whole but each
/// stage's buffers only for one band of `band_pixels` (halos included).
double estimated_peak_bytes(const std::vector<Command>& commands, double pixels, int channels,
                            int threads, double band_pixels = 0);

/// Keeps the memory a frame's buffers free in the process for the next ones: large
/// allocations come from the heap, not from mmap, and freed memory is not handed back to the
/// kernel. A buffer mapped afresh costs the kernel clearing each of its pages (a third of a
/// chain's CPU on frames of many channels); reused memory does not. Peak memory is the same:
/// it is what the largest stage holds at once. For the process that owns main() only.
void keep_freed_memory();

/// Memory this process may still use: $MCDN_MEMORY_LIMIT when set (bytes, or with a G or M
/// suffix: a farm slot's limit), else MemAvailable + SwapFree of /proc/meminfo, at most what
/// the container's cgroup still allows; 0 when unknown. False with `error` for a
/// $MCDN_MEMORY_LIMIT that is not such a number.
bool available_bytes(double& bytes, std::string& error);

/// False with `error` when the estimate for the frame the -i inputs describe is above
/// what is available: the error names both sizes and what would need less.
bool check_memory(const std::vector<Command>& commands, int threads, int parallel_frames,
                  std::string& error);

}  // namespace mcdntool
