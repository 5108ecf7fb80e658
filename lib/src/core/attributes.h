// The attributes ops hand each other on the ImageSpecs they pass along.
#pragma once

namespace mcdn {

/// Which denoiser made a frame's colour. The denoiser ops set it on their output; sure's
/// output is the denoiser's frame with SURE's channels added, so it carries it on; mix picks
/// the mixing network trained for that denoiser by it (PD §5.3 trains one h_NN per
/// denoiser: ours differ most where the KPCN op beats NFOR, models/README.md).
constexpr const char* kDenoiserAttribute = "mcdn:denoiser";

/// Set by sure on the probed inputs it hands the denoiser (PD §3.2): denoisers may skip
/// work only y needs (the extra AOVs).
constexpr const char* kProbeAttribute = "mcdn:sure_probe";

/// Set by sure, with kProbeAttribute, on the input of a probe: of the result it reads the
/// colour alone (by name), so an op may return just the colour channels (the cnn op does;
/// a frame-sized copy less per probe). compose keeps it for a chain's last stage only.
constexpr const char* kColorOnlyAttribute = "mcdn:color_only";

/// Channel names, one a line, that an op copying its input (prepare_op) appends, zero, to
/// its output, and then drops from the output's attributes. sure sets it on the input of
/// its unprobed run when that input is the caller's own frame rather than a copy with room
/// for sure's channels: the denoiser's copy then has the room, and becomes sure's output
/// without another frame-sized copy. An op that does not copy its input ignores it.
constexpr const char* kOutputRoomAttribute = "mcdn:output_room";

/// A tile map (skip/converged_tiles.h's encoding) a denoiser decided from its input and set
/// on its output (nfor's safety net, skip/worse_tiles.h). sure sets it on its probes' input,
/// where the denoiser uses it instead of deciding anew: a probe then differs from the
/// unprobed run only by the probe (PD §2.3's finite difference would jump where a tile's
/// decision flipped). Not written to files.
constexpr const char* kDenoiserTilesAttribute = "mcdn:denoiser_tiles";

/// On a merged render (mcdn/io.h read_inputs): the channels write_image writes by default,
/// one name a line — the render's own, and those a stage was asked to add (add_channels).
constexpr const char* kOutputChannelsAttribute = "mcdn:output_channels";

/// On a buffer mcdn::into_working_space converted (mcdn/color.h): its colour channels are in
/// the working space and its factored extras hold light, whatever its other attributes say;
/// ops do not convert it again. out_of_working_space drops it.
constexpr const char* kInWorkingSpaceAttribute = "mcdn:in_working_space";

}  // namespace mcdn
