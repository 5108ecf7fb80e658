// Reading renders into one merged buffer, checking them, and writing results safely.
//
// Ops never open files: front ends call these, then hand ImageBufs to the ops.
#pragma once

#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/version.h"

namespace mcdn {

/// Checks that `path` is a regular file this process can read, before anything opens it:
/// a FIFO, socket or device (/dev/zero) would hang a reader or feed it without end, a
/// folder is not a file. False with a one-line `error` naming the path.
bool check_input_file(const std::string& path, std::string& error);

/// Reads every channel of every subimage (multi-part EXR) of `path` into a float buffer.
/// The first part's channels keep their names (the beauty, in a renderer's multi-part file);
/// the other parts' are prefixed with their part name unless they already carry it.
/// Errors (unreadable, truncated, not an image) are set on `dst`, naming the file.
bool read_image(ImageBuf& dst, const std::string& path);

/// Reads a Tungsten-style directory (color, albedo, normal, depth, visibility; each as mean
/// `X.pfm`, halves `XA.pfm`/`XB.pfm` and `XVariance.pfm`) into the generic layout:
/// R,G,B / albedo.* / N.X,Y,Z / Z / visibility, with variance.*, A.*, B.* faces.
bool read_tungsten_directory(ImageBuf& dst, const std::string& dir);

/// K >= 2 renders of one frame that differ only in their sampling seed (Cycles' Seed,
/// Arnold's AA_seed), read as one render: every channel's mean (the render at K times the
/// samples), then "variance." + name, the variance of that mean (the seeds' sample
/// variance over K), and for an even K "A." / "B." + name, the means of the first and of
/// the last K/2 seeds (two independent halves). Identifier channels (Cryptomatte, Blender's
/// IndexOB/IndexMA) are the first seed's, with no faces. Every seed must have the same
/// channels and data window; errors on `dst` name the file and the channel.
bool combine_seeds(ImageBuf& dst, const std::vector<std::string>& seeds);

/// Reads all inputs and merges them into one float buffer: channels of `InputKind::Mean`
/// files keep their names, the others get the prefix of their kind (aov.h). Sizes and data
/// windows must agree. Sets kInputsAttribute (mcdn/aov.h: which file gave which prefix) and
/// "mcdn:output_channels" (the channels -o writes by default: those of the mean inputs).
bool read_inputs(ImageBuf& dst, const std::vector<InputFile>& inputs);

/// Which channels of the variance and half-buffer files read_inputs reads: the render's own
/// are always read whole (they are what -o writes), and by default so are the others. With
/// `only_roles`, a variance or half file's channel is read only when it is a face of a role
/// (or extra AOV) that `aovs` resolves to, or of one of `extra_features`; with `halves`
/// false, no half-buffer channel (a chain without NFOR and with a colour variance): the half
/// files are then only checked, from their headers, to hold the colour's half; with
/// `light_split` false, no face of the light components that only the CNN splits the colour
/// into (diffuse, specular and Blender's factors of them, emission, environment, the
/// transmission passes): a chain without the CNN. Their means are read (they are written).
/// With `all_variances` false, of the variance and half files only the colour's faces: a
/// chain whose stages read no other role's variance (--oidn, whose outlier rule reads the
/// colour's; --sure; --mix).
struct InputSelection {
    bool only_roles = false;
    bool halves = true;
    bool light_split = true;
    bool all_variances = true;
    AovSpec aovs;
    std::vector<std::string> extra_features;
    /// Blender view layers whose faces are read too, each as `aovs` with its layer (a
    /// file's every layer denoised in turn: mcdntool).
    std::vector<std::string> layers;
};
bool read_inputs(ImageBuf& dst, const std::vector<InputFile>& inputs,
                 const InputSelection& selection);
/// Whether `inputs` give the colour a variance: a variance file, or seeds.
bool gives_variance(const std::vector<InputFile>& inputs);

/// The merged frame read_inputs makes, a band of rows at a time: open() reads and checks
/// every header (names, windows, the selection), read() the pixels of some rows, so that a
/// chain in bands (mcdn/chain.h) holds one band of the inputs, never the frame.
class InputRows {
public:
    InputRows();
    ~InputRows();
    InputRows(InputRows&&) noexcept;
    InputRows& operator=(InputRows&&) noexcept;

    /// false with `error` (naming the file) on what read_inputs would refuse from headers.
    bool open(const std::vector<InputFile>& inputs, const InputSelection& selection,
              std::string& error);
    /// read_inputs's spec: every channel, the whole window (no pixels).
    const ImageSpec& spec() const { return m_spec; }
    /// Rows [ybegin, yend) of the frame, every channel, into a float buffer of those rows.
    /// `channels` (one per channel of spec()), when given: only the files holding one that
    /// is true are decoded; the other channels are zero, or what an earlier read left in
    /// `dst`: a dst of the same shape is read into again. Not thread-safe (one file handle
    /// per input, kept open between reads).
    bool read(ImageBuf& dst, int ybegin, int yend, std::string& error,
              const std::vector<bool>& channels = {}) const;

private:
    struct Files;
    std::unique_ptr<Files> m_files;
    ImageSpec m_spec;
};

/// Checks the values an op will read: NaN, Inf, |v| > kHugeValue in colour, halves and
/// features, negative variance, a normal longer than kMaxNormalLength. Feature variances
/// may hold NaN (renderers leave pixels without a feature sample; Tungsten does): those
/// are allowed and treated as unknown. The error names the file, the channel and the first
/// bad pixel. Nothing an op reads is changed silently: what passes here reaches the ops as
/// it is.
constexpr float kHugeValue = 1e15f;  // squares and window sums of such values stay finite
/// A normal is a direction (unit, or shorter where a pixel averages several): one longer
/// than this is not one, and would swamp the networks' and the regressions' features.
constexpr float kMaxNormalLength = 2.0f;
bool validate_inputs(const ImageBuf& merged, const AovSet& aovs, std::string& error);

/// Checks that the colour's half buffers are this render's: their mean (A+B)/2 is the
/// render's colour up to its noise (the variance, or ((A-B)/2)^2 without one) and rounding.
/// Over the whole buffer (a band's rows, streamed) a mismatch is an error naming the half
/// files (halves of another frame, mirrored, another render): NFOR would output the halves'
/// image. A 32x32 tile (kConvergedTileSize) with a pixel far off (a corrupt block in one
/// half) has its colour halves set to the render there: `repaired_tiles` gets each such
/// tile's first pixel (x, y) in the frame's coordinates, for the caller to say (a fallback
/// is never silent). True without halves.
bool check_halves(ImageBuf& merged, const AovSet& aovs,
                  std::vector<std::pair<int, int>>& repaired_tiles, std::string& error);

/// What every read of a render is checked for before any stage runs (mcdntool's frame,
/// its bands and its cross-frame neighbours, the OIIO plugin's bands): validate_inputs,
/// then check_halves. Reads of rows that overlap (a chain's bands and their halos,
/// mcdn/chain.h: on the tile grid) count a repaired tile once.
class InputChecks {
public:
    bool check(ImageBuf& rows, const AovSet& aovs, std::string& error);
    /// The tiles whose halves check_halves repaired, over every check() so far, each once.
    int repaired_tiles() const { return int(m_repaired.size()); }

private:
    std::set<std::pair<int, int>> m_repaired;
};

/// The type each of `channels` of `image` (read_inputs's frame, or a chain's result) is
/// written as: `datatype`, or where that is UNKNOWN as the render's file had it (half, uint:
/// a half beauty stays half, as oiiotool keeps it), float for the channels the stages added
/// and for types OpenEXR has not (an 8-bit PNG's). write_image's rule, and the OIIO
/// plugin's for the image it hands oiiotool.
std::vector<OIIO::TypeDesc> written_types(const ImageSpec& image,
                                          const std::vector<std::string>& channels,
                                          OIIO::TypeDesc datatype = OIIO::TypeDesc::UNKNOWN);
/// Puts `types` (one per channel) on `spec` as OIIO says them: one type, as its format;
/// mixed, format float and channelformats the types (none: float).
void set_channel_types(ImageSpec& spec, const std::vector<OIIO::TypeDesc>& types);
/// Finite values beyond half's range are written as +-kHalfMax in a half channel (half would
/// make them Inf), and said (write_image's warnings).
constexpr float kHalfMax = 65504.0f;

struct WriteOptions {
    /// half or float for every channel; UNKNOWN (the default): each channel as the render's
    /// file had it (a half beauty and float depth stay so, as oiiotool keeps them), float for
    /// the channels the stages added. Half keeps files small; variances may underflow in half.
    OIIO::TypeDesc datatype = OIIO::TypeDesc::UNKNOWN;
    /// An OpenEXR compression (check_compression); empty (the default): the render's own
    /// (DWAA at its level stays DWAA), zip where it had none OpenEXR knows.
    std::string compression;
    /// Channels to write, by name; empty = "mcdn:output_channels" or else every channel.
    std::vector<std::string> channels;
    /// Appended to the image's `Software` metadata (after "; ", once), as oiiotool records
    /// itself: what made the file. Empty: `Software` is written as it is.
    std::string software = software_name();
    /// Appended as a line to the image's `Exif:ImageHistory`, as oiiotool records its own
    /// command line there (mcdntool: its command line). Empty: left as it is.
    std::string history;
};

/// The compressions write_image accepts, OpenEXR's names (an optional ":LEVEL" for zip, zips,
/// dwaa and dwab); other formats ignore what they do not have. False with `error` otherwise.
bool check_compression(const std::string& compression, std::string& error);

/// Checks that `path` may be written by a run that reads `inputs`, before any work: it is
/// not one of them (the same name, or the same file through a link or another name), not a
/// directory, in a folder that exists and can be written, and not an existing file the user
/// could not write (replacing it through the rename would bypass its permissions; cp and
/// oiiotool refuse too). The error names the path and the reason.
bool check_output_path(const std::string& path, const std::vector<std::string>& inputs,
                       std::string& error);

/// Who writes a temporary output: this PID namespace's inode and this host's name
/// ("4026531836-node07"), as temporaries' names carry it after the writer's PID.
const std::string& temporary_owner();

/// Writes `src` to `path` through a temporary file in the same directory
/// (`.NAME.mcdn-tmp-PID-N-OWNER`, temporary_owner()), renamed into place only when
/// complete: a failed write never leaves a partial `path`; a replaced file keeps its mode.
/// Refuses what check_output_path refuses, with `src`'s own input files (merged_input_files)
/// as the inputs. Temporaries that a killed run left for the same `path` are removed first:
/// those of this owner whose PID no longer runs, and those of any other owner (another
/// host or container on shared storage: its PID cannot be checked here) only when not
/// written for 24 hours. Metadata of `src` is kept (mcdn:*
/// bookkeeping attributes excepted). Errors go to `error`; `warnings`, when given, gets a
/// line per channel that is written with NaN or Inf values (they came with the input: no op
/// makes them) and per channel whose values beyond half's range were clamped to +-65504
/// for a half output (half would turn them into Inf).
bool write_image(const ImageBuf& src, const std::string& path, const WriteOptions& options,
                 std::string& error, std::vector<std::string>* warnings = nullptr);

/// write_image in rows, as a chain makes them (run_chain's BandSink): open() with the spec
/// of the image to come (every channel; the same checks, channel choice and metadata as
/// write_image), write_rows() top to bottom, close() renames the file into place and adds
/// write_image's warnings. A writer destroyed before close() removes its temporary. A
/// multi-part image is refused (write_image writes it whole).
class RowWriter {
public:
    RowWriter();
    ~RowWriter();
    RowWriter(const RowWriter&) = delete;
    RowWriter& operator=(const RowWriter&) = delete;
    bool open(const ImageSpec& image, const std::string& path, const WriteOptions& options,
              std::string& error);
    /// Rows [own.ybegin, own.yend) of `band` (which may hold more rows), all of the image's
    /// width, the next rows of the file.
    bool write_rows(const ImageBuf& band, const ROI& own, std::string& error);
    bool close(std::string& error, std::vector<std::string>* warnings = nullptr);

private:
    struct State;
    std::unique_ptr<State> m;
};

/// Removes every temporary file a write_image in progress has open, for a signal handler
/// (async-signal-safe: unlink() of paths stored beforehand). The interrupted write then
/// fails; the program is expected to exit.
void remove_temporary_outputs();

}  // namespace mcdn
